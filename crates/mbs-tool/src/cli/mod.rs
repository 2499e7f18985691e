//! Pieces shared by the subcommands: parallel batches with a
//! progress bar and a summary, thread-pool setup, ONNX Runtime flags, the
//! pairs, the images eval and benchmark score, and the disparity source.

pub mod batch;
pub mod flags;
pub mod folders;
pub mod onnx;
pub mod pairs;
pub mod processes;
pub mod report_error;
pub mod rig;
pub mod scoring;
pub mod source;
pub mod synthesis;

use std::path::{Path, PathBuf};

use mbs_core::inputs::InputFiles;
use mbs_core::lock::Share;
use mbs_core::out_dir::{OutDir, Written};
use mbs_train::launch::LaunchError;
pub mod values;

/// Flags that cannot work together or with the settings, found after
/// parsing (e.g. more devices than batch items): the command exits with
/// status 2, as for clap's own usage errors.
#[derive(Debug)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// The exit status of a command that failed with `error`: 2 for a usage
/// error (ours, or settings the devices of a launch cannot run: more
/// sharers than batch items, no device), 1 otherwise.
pub fn exit_status(error: &anyhow::Error) -> u8 {
    let usage = |cause: &(dyn std::error::Error + 'static)| {
        cause.is::<UsageError>() || matches!(cause.downcast_ref(), Some(LaunchError::Usage(_)))
    };
    if error.chain().any(usage) { 2 } else { 1 }
}

/// Takes the output folder `dir` for `command` ([`OutDir::take`]: made and
/// locked for this process or its `shard`) once every one of `outputs`
/// has passed the checks, before and again under the lock: none replaces
/// one of `inputs` or a file mbs did not write there. The outputs are then
/// recorded as the command's (so a later `--overwrite` may replace them)
/// and the temporary files killed runs left are removed.
pub fn take_out(
    dir: &Path,
    shard: Option<mbs_core::shard::Shard>,
    command: &str,
    inputs: &InputFiles,
    outputs: &[PathBuf],
) -> anyhow::Result<OutDir> {
    let check = |written: &Written| -> anyhow::Result<()> {
        for output in outputs {
            inputs.refuse(output)?;
            mbs_core::atomic::refuse_special_target(output)?;
            written.refuse_foreign(output)?;
        }
        Ok(())
    };
    check(&Written::read(dir)?)?;
    let share = match shard {
        Some(shard) => Share::Shard {
            index: shard.index,
            count: shard.count,
        },
        None => Share::Whole,
    };
    let out = OutDir::take(dir, share, &format!("mbs-tool {command}"))?;
    if let Some(warning) = out.lock_warning() {
        eprintln!("warning: {warning}");
    }
    check(out.written())?;
    out.record(outputs)?;
    let removed = out.remove_stale_partials()?;
    if removed > 0 {
        eprintln!(
            "removed {removed} temporary file(s) left in {} by a killed run",
            dir.display()
        );
    }
    Ok(out)
}

/// [`take_out`] for a command whose files depend on `settings`: a folder
/// whose files were written with other settings is refused, naming what
/// differs, before anything is written (unless `overwrite`: every output is
/// then recomputed), and the settings are kept in the folder
/// ([`mbs_core::batch_settings`]). A resumed run skips the files that
/// exist, so without this a rerun with another model or seed would mix
/// two kinds of file in one folder.
pub fn take_out_settled(
    dir: &Path,
    shard: Option<mbs_core::shard::Shard>,
    command: &str,
    (inputs, outputs): (&InputFiles, &[PathBuf]),
    settings: &serde_json::Value,
    overwrite: bool,
) -> anyhow::Result<OutDir> {
    if !overwrite {
        mbs_core::batch_settings::check(dir, command, settings)?;
    }
    let out = take_out(dir, shard, command, inputs, outputs)?;
    mbs_core::batch_settings::keep(dir, command, settings)?;
    Ok(out)
}

/// Checks that an input `path` given as `what` (e.g. "left view") is a file.
pub fn require_file(path: &std::path::Path, what: &str) -> anyhow::Result<()> {
    match mbs_core::regular::not_a_file(path, what) {
        Some(message) => anyhow::bail!(message),
        None => Ok(()),
    }
}
