//! `mbs-tool train`: S3 self-supervised training of the built-in stereo
//! network on a manifest's multi-view samples (conventions §5), with periodic
//! validation, checkpoints and resumption.

mod report;

use std::path::{Path, PathBuf};
use std::rc::Rc;

use anyhow::{Context, bail};
use clap::Parser;
use mbs_nets::BackboneKind;
use mbs_nets::device::DeviceList;
use mbs_train::RunConfig;
use mbs_train::checkpoint::Checkpoint;
use mbs_train::distributed::Collective;
use mbs_train::launch::{
    Beginning, Ended, Launch, ReportedByRankZero, Stopped, settle, stop_requests,
};
use mbs_train::precision::Precision;
use mbs_train::run::{Quiet, Start, TrainingRun, computing_differences};

use report::Report;

/// Arguments of `train`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool train mbs-demo/train-data/manifest.json --out runs/demo \
      --steps 300 --batch-size 4 --crop 96x160 --max-disparity 64
  mbs-tool train mbs20k.json --out runs/pretrain     # the paper's pretraining
  mbs-tool train kitti.json --out runs/ft --config ft.json --set trainer.loss.omega=3
  mbs-tool train data.json --out runs/a --set trainer.loss.geometry=false   # Table 3 (A)
  mbs-tool train --print-config > my.json            # every setting, with defaults
  mbs-tool train mbs20k.json --out runs/raft --backbone raft-stereo --crop 384x512
  mbs-tool train kitti-mb.json --out runs/ft --backbone raft-stereo --init runs/raft --lr 5e-5
  mbs-tool train mbs20k.json --out runs/vk --device vulkan          # any Vulkan GPU
  mbs-tool train mbs20k.json --out runs/dp --device cuda:0,cuda:1   # data parallel (--features cuda)
  mbs-tool train mbs20k.json --out runs/amp --device cuda --precision bf16  # mixed precision
  mpirun -np 8 mbs-tool train mbs20k.json --out runs/mpi --device cuda  # 8 processes (--features mpi)
  srun --ntasks-per-node=8 --gpus-per-node=8 mbs-tool train mbs20k.json --out runs/slurm --device cuda

Training uses the manifest's `train` samples; validation scores the
teacher on the `val` samples (or `test` when there is no `val`) that have
ground truth for the validation pairs. Outputs in --out: config.json,
train.jsonl (loss terms, LR, samples/s), val.jsonl (EPE, Out-1/2/3 over
ALL/NOC/OCC), loss.png and val.png (curves), visuals/step-N/*.png (reference
| teacher | student | GT | weight map: red = occluded for the teacher, green
= seen by the teacher only), tensorboard/ (every logged number and the
sheets: tensorboard --logdir RUN), checkpoints/step-N/.

Ctrl-C (or SIGTERM, or SIGUSR1) saves a checkpoint and stops; running the
same command again resumes from the newest checkpoint (--restart discards
them). The settings are the paper's defaults (a resumed run: its
checkpoint's settings), overlaid by --config, then by the named flags, then
by --set KEY=VALUE (see schemas/train-config.schema.json).

Under mpirun or srun (a build with `--features mpi`), each process is one
rank of a data-parallel run: the ranks check that they run the same settings
on the same manifest, share each batch (the global --batch-size, drawn as one
process would), sum their gradients with MPI, and compare their weights at
every validation; rank 0 alone validates and writes --out (on storage every
rank can read, for resuming). A run resumes on any number of ranks. To stop
one with a checkpoint, send mpirun SIGUSR1 (kill -USR1 PID; under SLURM:
scancel --signal=USR1 JOB), which it forwards to every rank at once.")]
pub struct Args {
    /// The dataset manifest (see `mbs-tool scan`, `synth`, `extrapolate`).
    #[arg(required_unless_present = "print_config")]
    pub manifest: Option<PathBuf>,
    /// Output folder of the run.
    #[arg(long, required_unless_present = "print_config")]
    pub out: Option<PathBuf>,
    /// A JSON file with any subset of the settings.
    #[arg(long, value_name = "FILE.json")]
    pub config: Option<PathBuf>,
    /// Any setting, e.g. `trainer.loss.omega=3` or `data.val_pairs=[[0,1],[2,1]]`
    /// (repeatable; applied after the named flags).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Optimiser steps (trainer.lr.total_steps).
    #[arg(long)]
    pub steps: Option<usize>,
    /// Batch size (data.batch_size).
    #[arg(long)]
    pub batch_size: Option<usize>,
    /// Random crop HEIGHTxWIDTH (data.crop_height, data.crop_width).
    #[arg(long, value_name = "HxW", value_parser = crate::cli::values::size)]
    pub crop: Option<(usize, usize)>,
    /// Peak learning rate (trainer.lr.max_lr).
    #[arg(long)]
    pub lr: Option<f64>,
    /// Largest disparity of the data (network.max_disparity): the compact
    /// network's range, a multiple of 4.
    #[arg(long)]
    pub max_disparity: Option<usize>,
    /// The network trained (network.backbone): compact, raft-stereo or igev.
    #[arg(long, value_name = "NAME", value_parser = crate::cli::values::backbone)]
    pub backbone: Option<BackboneKind>,
    /// Start a new run from these weights instead of fresh ones (student and
    /// teacher both; the schedule and optimiser start afresh): another run
    /// or checkpoint folder (its teacher), an official checkpoint (.pth or
    /// .safetensors) or an `mbs-tool export`. A resumed run ignores it.
    #[arg(long, value_name = "RUN|FILE")]
    pub init: Option<PathBuf>,
    /// Seed of the weights and of every random choice (seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Validate every N steps (val_every).
    #[arg(long)]
    pub val_every: Option<usize>,
    /// Save a checkpoint every N steps (checkpoint_every).
    #[arg(long)]
    pub checkpoint_every: Option<usize>,
    /// Where to train: cpu, vulkan[:N] (any Vulkan GPU; N counts discrete
    /// GPUs), or cuda[:N] in a build with `--features cuda`. A comma-separated
    /// list (cuda:0,cuda:1) trains data parallel: each device takes a share of
    /// every batch and the gradients are summed on the first one. Under
    /// mpirun or srun each process takes the list: `cuda` (or `vulkan`)
    /// means GPU LOCAL_RANK, the process's rank on its machine (from MPI,
    /// whatever the launcher), so N processes per node use its first N GPUs;
    /// a list of K (`cuda,cuda`) gives each process GPUs K*LOCAL_RANK to
    /// K*LOCAL_RANK+K-1, whose gradients it sums before the processes do.
    #[arg(long, default_value = "cpu", value_parser = crate::cli::values::devices)]
    pub device: DeviceList,
    /// The format the networks compute in (trainer.precision): f32, or mixed
    /// precision with bf16 or f16 (weights, optimiser state and losses stay
    /// f32; f16 scales its loss dynamically). A device that cannot compute in
    /// the format is refused at start (most Vulkan drivers lack bf16). The
    /// CPU has both but runs them slower than f32: only GPUs gain.
    #[arg(long, value_name = "FORMAT", value_parser = crate::cli::values::precision)]
    pub precision: Option<Precision>,
    /// Discard the checkpoints in --out and start from fresh weights.
    #[arg(long)]
    pub restart: bool,
    /// Print the effective settings as JSON and exit.
    #[arg(long)]
    pub print_config: bool,
    /// Worker threads for the network.
    #[command(flatten)]
    pub threads: crate::cli::flags::Jobs,
}

impl Args {
    /// The flags as `KEY=VALUE` overrides, before the `--set` ones.
    fn overrides(&self) -> Vec<String> {
        let mut out = Vec::new();
        let mut push = |key: &str, value: Option<String>| {
            if let Some(value) = value {
                out.push(format!("{key}={value}"));
            }
        };
        push("trainer.lr.total_steps", self.steps.map(|v| v.to_string()));
        push("data.batch_size", self.batch_size.map(|v| v.to_string()));
        push("data.crop_height", self.crop.map(|c| c.0.to_string()));
        push("data.crop_width", self.crop.map(|c| c.1.to_string()));
        push("trainer.lr.max_lr", self.lr.map(|v| v.to_string()));
        push(
            "network.max_disparity",
            self.max_disparity.map(|v| v.to_string()),
        );
        push("network.backbone", self.backbone.map(|b| b.to_string()));
        push("trainer.precision", self.precision.map(|p| p.to_string()));
        push("seed", self.seed.map(|v| v.to_string()));
        push("val_every", self.val_every.map(|v| v.to_string()));
        push(
            "checkpoint_every",
            self.checkpoint_every.map(|v| v.to_string()),
        );
        out.extend(self.set.iter().cloned());
        out
    }

    /// The effective configuration: over the defaults, or over the
    /// settings of the checkpoint this run resumes from.
    fn run_config(&self) -> anyhow::Result<RunConfig> {
        let resumed = match (&self.out, self.restart) {
            (Some(out), false) => Checkpoint::latest(out)?,
            _ => None,
        };
        let saved = resumed.map(|checkpoint| checkpoint.config()).transpose()?;
        self.settings(saved.as_ref())
    }

    /// The user's file and flags over `base` (a checkpoint's settings), or
    /// over the defaults.
    fn settings(&self, base: Option<&RunConfig>) -> anyhow::Result<RunConfig> {
        let file = self
            .config
            .as_deref()
            .map(RunConfig::read_file)
            .transpose()?;
        let overrides = self.overrides();
        let config = match base {
            Some(base) => RunConfig::resumed(base, file.as_ref(), &overrides),
            None => RunConfig::layered(file.as_ref(), &overrides),
        };
        config.with_context(|| match &self.config {
            Some(path) => format!("settings from {} and the flags", path.display()),
            None => "settings from the flags".into(),
        })
    }
}

/// Runs `train`: in this process alone, or as one rank of the processes
/// `mpirun`/`srun` started (a build with `--features mpi`), whose errors
/// end the ranks as [`settle`] says.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.run_config()?;
    if args.print_config {
        println!("{:#}", config.to_json()?);
        return Ok(());
    }
    let (Some(manifest), Some(out)) = (&args.manifest, &args.out) else {
        bail!("give a MANIFEST and --out DIR");
    };
    args.threads.start()?;
    let processes = crate::cli::processes::join()?;
    match (
        train(&args, config, manifest, out, processes.clone()),
        processes,
    ) {
        (Err(e), Some(processes)) => {
            let description = crate::cli::report_error::describe(&e);
            Err(settle(processes.as_ref(), e.as_ref(), &description).into())
        }
        (result, _) => result,
    }
}

/// Trains into `out`; with `processes`, as this process's rank of them:
/// the run launched, then trained until its end or a stop request.
fn train(
    args: &Args,
    config: RunConfig,
    manifest: &Path,
    out: &Path,
    processes: Option<Rc<dyn Collective>>,
) -> anyhow::Result<()> {
    let spread = processes.as_ref().map(|p| p.size());
    let launched = Launch {
        manifest,
        out,
        config,
        devices: &args.device,
        processes,
        beginning: Beginning {
            init: args.init.as_deref(),
            restart: args.restart,
        },
        reduction: None,
    }
    .open()?;
    for warning in &launched.warnings {
        eprintln!("warning: {warning}");
    }
    if launched.removed_partials > 0 {
        eprintln!(
            "removed {} temporary file(s) left in {} by a killed run",
            launched.removed_partials,
            out.display()
        );
    }
    let writer = launched.is_writer();
    if writer && !launched.is_complete() {
        announce(args, &launched.run, launched.start, out, spread);
    }
    let stop = stop_requests()?;
    let mut report = match writer && !launched.is_complete() {
        true => Some(Report::new(
            out,
            launched.run.config(),
            launched.run.steps_taken(),
        )?),
        false => None,
    };
    let end = match report.as_mut() {
        Some(report) => launched.train(report, &stop)?,
        None => launched.train(&mut Quiet, &stop)?,
    };
    if let Some(report) = report.as_mut() {
        report.finish()?;
    }
    match end {
        Ended::Complete { steps, total } if writer => eprintln!(
            "train: {} is complete ({steps} of {total} steps); --restart to train again",
            out.display()
        ),
        Ended::Complete { .. } => {}
        Ended::Stopped { steps, total } if writer => return Err(Stopped { steps, total }.into()),
        Ended::Stopped { .. } => return Err(ReportedByRankZero.into()),
        Ended::Finished { metrics } => {
            if let Some(report) = report {
                report.summary(metrics.as_deref());
            }
        }
    }
    Ok(())
}

/// Says what the run does: where it starts, on how many processes, and
/// whether it validates.
fn announce(
    args: &Args,
    training: &TrainingRun,
    start: Start,
    out: &Path,
    processes: Option<usize>,
) {
    let total = training.config().steps();
    let spread = match processes {
        Some(processes) => format!(" on {processes} processes"),
        None => String::new(),
    };
    match start {
        Start::Fresh => match &args.init {
            Some(init) => eprintln!(
                "train: {total} steps into {}{spread}, starting from {}",
                out.display(),
                init.display()
            ),
            None => eprintln!("train: {total} steps into {}{spread}", out.display()),
        },
        Start::Resumed(steps) => {
            eprintln!(
                "train: resuming {} at step {steps} of {total}{spread}{}",
                out.display(),
                if args.init.is_some() {
                    " (its checkpoint's weights; --init applies to new runs)"
                } else {
                    ""
                }
            );
            // Settings whose defaults changed since the run began.
            let kept = args
                .settings(None)
                .ok()
                .and_then(|today| computing_differences(training.config(), &today).ok())
                .unwrap_or_default();
            if !kept.is_empty() {
                eprintln!(
                    "train: the run keeps its checkpoint's settings where today's defaults differ (checkpoint -> default): {}",
                    kept.join(", ")
                );
            }
        }
    }
    if training.validation().is_empty() {
        eprintln!(
            "train: no held-out sample has ground truth for {:?}: validation is off",
            training.config().data.val_pairs
        );
    }
}
