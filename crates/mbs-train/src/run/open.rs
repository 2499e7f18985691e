//! Opening a run, as named steps the launcher takes ([`crate::launch`];
//! where it trains is chosen before, by [`super::place`]): its data, its
//! first weights or those of a checkpoint, and the output folder.

use std::path::{Path, PathBuf};
use std::sync::PoisonError;

use burn::module::Module;
use burn::tensor::Device;
use mbs_dataset::Manifest;

use super::logs::truncate_log;
use super::resume::check_resumable;
use super::{
    CONFIG_FILE, LOSS_PLOT, Start, TENSORBOARD_DIR, TRAIN_LOG, VAL_LOG, VAL_PLOT, VISUALS_DIR,
    initial_weights,
};
use crate::WEIGHT_DRAWING;
use crate::checkpoint::Checkpoint;
use crate::config::RunConfig;
use crate::data::{TrainingSamples, ValidationSet};
use crate::error::TrainError;
use crate::step::S3Trainer;
use mbs_core::atomic::write_bytes_atomic;
use mbs_core::inputs::InputFiles;
use mbs_core::lock::{FolderLock, Share};
use mbs_core::out_dir::{OutDir, Written};
use mbs_nets::StereoNetwork;
use mbs_nets::checkpoint::CHECKPOINTS_DIR;

/// The training samples of `manifest` (their files checked) and the
/// held-out pairs validation scores.
pub(crate) fn load_data(
    manifest: &Path,
    config: &RunConfig,
) -> Result<(TrainingSamples, ValidationSet), TrainError> {
    let parsed = Manifest::load(manifest)?;
    let crop = (config.data.crop_height, config.data.crop_width);
    let samples = TrainingSamples::from_manifest(manifest, &parsed, crop)?;
    samples.check_files(manifest)?;
    let validation = ValidationSet::from_manifest(
        manifest,
        &parsed,
        &config.data.val_pairs,
        (config.data.val_split, config.data.val_samples),
        config.data.val_protocol()?,
    )?;
    Ok((samples, validation))
}

/// The trainer a run starts with, its weights on `device`: those of
/// `latest` (the checkpoint it resumes), or fresh ones (see
/// [`first_student`]), `init`'s when given; and how it began.
pub(crate) fn trainer(
    config: &RunConfig,
    device: &Device,
    latest: Option<Checkpoint>,
    init: Option<&Path>,
) -> Result<(S3Trainer<StereoNetwork>, Start), TrainError> {
    let train_device = device.clone().autodiff();
    let init = init.filter(|_| latest.is_none());
    let student = first_student(config, &train_device, latest.is_none(), init)?;
    let mut trainer = S3Trainer::new(student, &config.trainer)?;
    let start = match latest {
        Some(checkpoint) => {
            resume(&mut trainer, &checkpoint, config, (device, &train_device))?;
            Start::Resumed(trainer.steps_taken())
        }
        None => Start::Fresh,
    };
    Ok((trainer, start))
}

/// The student the run starts from on `train_device`: fresh weights, drawn
/// on the CPU from the run's seed when `seeded` (a fresh run: a checkpoint
/// has its own) so that a seed gives the same network on every device,
/// then the weights of `init` when given.
fn first_student(
    config: &RunConfig,
    train_device: &Device,
    seeded: bool,
    init: Option<&Path>,
) -> Result<StereoNetwork, TrainError> {
    let init_device = Device::flex().autodiff();
    let drawing = WEIGHT_DRAWING
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    if seeded {
        init_device.seed(config.seed);
    }
    let fresh = config.network.init(&init_device)?;
    // Forking while `fresh` still shares the (lazy) parameters makes
    // burn initialise them where they are and copy them over.
    let student = fresh.clone().fork(train_device);
    drop(fresh);
    drop(drawing);
    match init {
        Some(init) => Ok(student.with_state_dict(&initial_weights(init)?, init)?),
        None => Ok(student),
    }
}

/// Puts `checkpoint`'s state into `trainer` (the teacher on `device`, the
/// student on `train_device`), once its settings allow resuming with
/// `config`.
fn resume(
    trainer: &mut S3Trainer<StereoNetwork>,
    checkpoint: &Checkpoint,
    config: &RunConfig,
    (device, train_device): (&Device, &Device),
) -> Result<(), TrainError> {
    check_resumable(checkpoint, config)?;
    let networks = checkpoint.networks()?;
    trainer.restore(
        networks.student(train_device)?,
        networks.teacher(device)?,
        checkpoint.optimizer()?,
        checkpoint.state.steps,
        checkpoint.state.loss_scale,
    );
    Ok(())
}

/// The writer's hold on the run folder between the launch's first step
/// and the folder's preparation.
pub(crate) enum FolderHold {
    /// This process does not write (a rank other than the writer).
    NotWriter,
    /// The folder exists and this process holds its lock.
    Locked(FolderLock),
    /// The folder does not exist yet: it is made, and taken, when the
    /// run is prepared (refused if another process made it meanwhile).
    Absent,
}

/// Who holds a run folder, as a refused second run names it.
const HOLDER: &str = "mbs-tool train";

/// Takes the lock of the run folder `out` for its writer (`writes`), at
/// once, so a second run, resume or restart into it is refused before it
/// changes anything there (the lock file is made, and names this run); a
/// file or a link to nothing in the folder's place is refused.
pub(crate) fn hold_folder(out: &Path, writes: bool) -> Result<FolderHold, TrainError> {
    if !writes {
        return Ok(FolderHold::NotWriter);
    }
    if out.exists() {
        // Refuses a file in the folder's place; makes nothing.
        mbs_core::confine::create_out_dir(out)?;
        return Ok(FolderHold::Locked(FolderLock::take(
            out,
            Share::Whole,
            HOLDER,
        )?));
    }
    if std::fs::symlink_metadata(out).is_ok() {
        return Err(TrainError::Input(format!(
            "{}: is a symbolic link to nothing; give the run's folder itself",
            out.display()
        )));
    }
    Ok(FolderHold::Absent)
}

/// Everything a run writes in its folder: files, then folders (with a
/// trailing `/`, recorded as covering what is under them).
fn run_outputs(out: &Path) -> (Vec<PathBuf>, Vec<PathBuf>) {
    let files = [CONFIG_FILE, TRAIN_LOG, VAL_LOG, LOSS_PLOT, VAL_PLOT];
    let folders = [CHECKPOINTS_DIR, VISUALS_DIR, TENSORBOARD_DIR];
    (
        files.iter().map(|f| out.join(f)).collect(),
        folders.iter().map(|f| out.join(format!("{f}/"))).collect(),
    )
}

/// Refuses, before anything in `out` is removed or written, a run whose
/// outputs would replace one of its `inputs` (or whose folders, which it
/// prunes, hold one), a file of the folder that mbs did not write, or a
/// special file (a FIFO log, a folder named `config.json`).
fn check_outputs(out: &Path, inputs: &InputFiles) -> Result<(), TrainError> {
    let written = Written::read(out)?;
    let (files, folders) = run_outputs(out);
    for file in &files {
        inputs.refuse(file)?;
        mbs_core::atomic::refuse_special_target(file)?;
    }
    for folder in &folders {
        if let Some(input) = inputs.inside(folder) {
            return Err(TrainError::Input(format!(
                "{}: the run writes and prunes {}, which holds its input {}; \
                 move the input or choose another --out",
                out.display(),
                folder.display(),
                input.display()
            )));
        }
    }
    for folder in &folders {
        if std::fs::symlink_metadata(folder).is_ok_and(|m| m.file_type().is_symlink()) {
            return Err(TrainError::Input(format!(
                "{}: is a symbolic link; the run prunes what is under it, so it must be \
                 the run's own folder",
                folder.display()
            )));
        }
    }
    // A run folder an mbs older than the record wrote is known by its
    // checkpoints' own state.json.
    if written.is_empty() && Checkpoint::latest(out).is_ok_and(|c| c.is_some()) {
        return Ok(());
    }
    for output in files.iter().chain(&folders) {
        written.refuse_foreign(output)?;
    }
    Ok(())
}

/// A run folder its writer has prepared: held as long as the run lives.
pub(crate) struct Prepared {
    /// The folder, locked.
    pub(crate) folder: OutDir,
    /// How many temporary files of killed runs were removed.
    pub(crate) removed_partials: usize,
}

/// Readies `out` for the run's writer (`hold`; nothing for the others):
/// every check first (its outputs against the run's `inputs` and the files
/// mbs did not write, see [`check_outputs`]); then the folder made or
/// taken, the outputs recorded, the temporary files a killed earlier run
/// left in it removed, its checkpoints removed when it `restart`s, the
/// logs cut back to a resumed run's step (or emptied for a fresh run), and
/// the configuration written.
pub(crate) fn prepare_folder(
    out: &Path,
    hold: FolderHold,
    inputs: &InputFiles,
    config: &RunConfig,
    (start, restart): (Start, bool),
) -> Result<Option<Prepared>, TrainError> {
    let folder = match hold {
        FolderHold::NotWriter => return Ok(None),
        FolderHold::Locked(lock) => {
            check_outputs(out, inputs)?;
            OutDir::with_lock(out, Share::Whole, lock)?
        }
        FolderHold::Absent => OutDir::take_new(out, Share::Whole, HOLDER)?,
    };
    let (files, folders) = run_outputs(out);
    folder.record(files.iter().chain(&folders))?;
    let removed_partials = folder.remove_stale_partials()?;
    if restart {
        crate::checkpoint::discard_all(out)?;
    }
    for log in [TRAIN_LOG, VAL_LOG] {
        let path = out.join(log);
        match start {
            Start::Resumed(steps) => truncate_log(&path, steps)?,
            // Emptied through the writer, which refuses a special file.
            Start::Fresh => write_bytes_atomic(&path, b"")?,
        }
    }
    let config_json = serde_json::to_vec_pretty(&config.to_json()?)
        .map_err(|e| TrainError::Config(e.to_string()))?;
    write_bytes_atomic(&out.join(CONFIG_FILE), &config_json)?;
    Ok(Some(Prepared {
        folder,
        removed_partials,
    }))
}
