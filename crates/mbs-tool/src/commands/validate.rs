//! `mbs-tool validate`: a manifest against its schema and the files on disk.

use std::path::PathBuf;

use clap::Parser;
use mbs_dataset::validate::{Progress, ValidateOptions, validate_manifest};

use crate::cli::batch::progress_bar;

/// Arguments of `validate`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool validate /data/MBS20K/manifest.json
  mbs-tool validate mbs-demo/data/manifest.json --deep --json > report.json

Checks: JSON Schema (schemas/manifest.schema.json), unique ids, views per
sample = cameras of the rig, every file exists and is complete, image sizes
match the rig, depth PNGs are 8-bit RGB, masks 8-bit grey, disparities float
maps or 16-bit PNGs, SHA-256 checksums when the manifest carries them.
Exit status 0 only when no problem is found (use it in CI).")]
pub struct Args {
    /// The manifest to check.
    pub manifest: PathBuf,
    /// Decode every pixel of every file (slower) instead of headers and
    /// trailers. Without it a file whose header is fine but whose pixels are
    /// corrupt passes as clean (`train` skips such images and lists them).
    #[arg(long)]
    pub deep: bool,
    /// Print a machine-readable JSON report on stdout instead of lines.
    #[arg(long)]
    pub json: bool,
    /// Worker threads.
    #[command(flatten)]
    pub threads: crate::cli::flags::Jobs,
}

/// A progress bar sized once the manifest is read.
struct BarProgress(indicatif::ProgressBar);

impl Progress for BarProgress {
    fn start(&self, samples: usize) {
        self.0.set_length(samples as u64);
    }

    fn advance(&self) {
        self.0.inc(1);
    }
}

/// Runs `validate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.threads.start()?;
    let bar = BarProgress(progress_bar(0, "samples"));
    let start = std::time::Instant::now();
    let report = validate_manifest(&args.manifest, ValidateOptions { deep: args.deep }, &bar);
    bar.0.finish_and_clear();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        for problem in &report.problems {
            println!("{problem}");
        }
        eprintln!(
            "validate: {}: {} samples, {} files checked{} in {:.2} s, {} problem(s)",
            report.manifest,
            report.samples,
            report.files_checked,
            if report.deep { " (deep)" } else { "" },
            start.elapsed().as_secs_f64(),
            report.problems.len()
        );
    }
    if !report.is_clean() {
        anyhow::bail!(
            "{}: {} problem(s) found",
            report.manifest,
            report.problems.len()
        );
    }
    Ok(())
}
