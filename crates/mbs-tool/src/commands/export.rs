//! `mbs-tool export`: a trained network as safetensors under the official
//! implementation's keys (for the official PyTorch code), or as an ONNX
//! model checked through ONNX Runtime, with the model card that runs it
//! and a deployment report (`mbs_export`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use burn::tensor::Device;
use clap::{Parser, ValueEnum};
use mbs_core::atomic::{refuse_special_target, write_bytes_atomic};
use mbs_core::inputs::InputFiles;
use mbs_export::{Export, Probe, Tolerance, export_checked, pair};
use mbs_nets::checkpoint::TrainedNetworks;
use mbs_nets::{BackboneKind, NetworkConfig, StereoNetwork};

use crate::cli::onnx::OnnxArgs;

/// Arguments of `export`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool export runs/raft --out teacher.safetensors
  mbs-tool export runs/raft/checkpoints/step-0005000 --student --out student.safetensors
  mbs-tool export runs/igev --out igev.onnx --size 384x1248
  mbs-tool export --backbone raft-stereo --weights raftstereo-middlebury.pth \\
      --out raft.onnx --size 480x640 --iters 32 --check-pair left.png right.png

RAFT-Stereo weights carry the official keys (princeton-vl/RAFT-Stereo), so
the official code loads them unchanged:

  from safetensors.torch import load_file
  model = RAFTStereo(args)        # the run's network.raft_stereo settings
  model.load_state_dict(load_file('teacher.safetensors'))

The compact network has no official implementation; its file holds mbs's
own parameter names, which `--init` and `--weights` read back.

An ONNX export (--format onnx, or an --out ending in .onnx) runs through
ONNX Runtime beside mbs's own forward pass on a real pair before anything
is written, and is refused when they differ by more than --tolerance. It
writes NAME.onnx, NAME.card.json (`predict --model NAME.onnx --card
NAME.card.json` runs it) and NAME.report.md (operators, static shapes,
TensorRT notes, half-precision range). See docs/deploying.md.")]
pub struct Args {
    /// A training run (its newest checkpoint) or a checkpoints/step-N folder.
    #[arg(required_unless_present = "weights", conflicts_with = "weights")]
    pub run: Option<PathBuf>,
    /// The file to write: FILE.safetensors, or FILE.onnx.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Export the student instead of the teacher.
    #[arg(long, requires = "run")]
    pub student: bool,
    /// The format [default: onnx when --out ends in .onnx, else safetensors].
    #[arg(long, value_enum)]
    pub format: Option<Format>,
    /// Official or exported weights to export instead of a run (ONNX only):
    /// a .pth or .safetensors state dict, as `--init` takes them.
    #[arg(long, value_name = "FILE", requires = "backbone")]
    pub weights: Option<PathBuf>,
    /// The network of --weights: compact, raft-stereo or igev.
    #[arg(long, value_name = "NAME", requires = "weights", value_parser = crate::cli::values::backbone)]
    pub backbone: Option<BackboneKind>,
    /// A network setting for --weights (repeatable), e.g. network.raft_stereo.n_downsample=3.
    #[arg(long = "set", value_name = "network.KEY=VALUE", requires = "weights")]
    pub set: Vec<String>,
    /// The ONNX model's fixed input size, HEIGHTxWIDTH (required for ONNX).
    #[arg(long, value_name = "HxW", value_parser = crate::cli::values::size)]
    pub size: Option<(usize, usize)>,
    /// Iterations of RAFT-Stereo or IGEV-Stereo in the ONNX model
    /// [default: the network's test_iters].
    #[arg(long, value_name = "N", value_parser = crate::cli::values::count)]
    pub iters: Option<usize>,
    /// ONNX operator set: 16, 17 or 18.
    #[arg(long, default_value_t = 17, value_parser = clap::value_parser!(i64).range(16..=18))]
    pub opset: i64,
    /// The pair the ONNX model is checked on [default: Middlebury's Teddy,
    /// built in], resized to --size.
    #[arg(long, num_args = 2, value_names = ["LEFT", "RIGHT"])]
    pub check_pair: Option<Vec<PathBuf>>,
    /// Largest mean and largest absolute difference (pixels) the check
    /// allows, MEAN,LARGEST.
    #[arg(long, value_name = "MEAN,LARGEST", default_value = "0.001,0.01", value_parser = tolerance)]
    pub tolerance: Tolerance,
    /// Measure every intermediate value on the check pair against half
    /// precision's range for the report (one ONNX Runtime run per 64
    /// values: minutes for RAFT-Stereo or IGEV-Stereo at full size).
    #[arg(long)]
    pub fp16_probe: bool,
    /// The ONNX Runtime library for the check.
    #[command(flatten)]
    pub runtime: OnnxArgs,
}

/// What `export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// safetensors under the official keys, for the official PyTorch code.
    Safetensors,
    /// An ONNX model with its card and report.
    Onnx,
}

/// Parses `MEAN,LARGEST`.
fn tolerance(text: &str) -> Result<Tolerance, String> {
    let bad = || format!("`{text}` is not MEAN,LARGEST in pixels, e.g. 0.001,0.01");
    let (mean, largest) = text.split_once(',').ok_or_else(bad)?;
    let value = |s: &str| {
        s.trim()
            .parse::<f32>()
            .ok()
            .filter(|v| *v >= 0.0)
            .ok_or_else(bad)
    };
    Ok(Tolerance {
        mean: value(mean)?,
        largest: value(largest)?,
    })
}

/// Runs `export`.
pub fn run(args: Args) -> anyhow::Result<()> {
    // The name as given first: a device such as /dev/null is refused as
    // itself, never written beside as /dev/null.safetensors.
    refuse_special_target(&args.out).context("--out")?;
    let onnx_name = args.out.extension().is_some_and(|ext| ext == "onnx");
    match args.format.unwrap_or(if onnx_name {
        Format::Onnx
    } else {
        Format::Safetensors
    }) {
        Format::Safetensors => safetensors(&args),
        Format::Onnx => onnx(&args),
    }
}

/// The network as a checked ONNX model with its card and report.
fn onnx(args: &Args) -> anyhow::Result<()> {
    let (height, width) = args
        .size
        .context("--size HEIGHTxWIDTH is needed for an ONNX export (its input size is fixed)")?;
    pair::check_size(height, width)
        .map_err(anyhow::Error::msg)
        .context("--size")?;
    let (network, what, mut read) = network(args)?;
    let (left, right, pair_files) = check_pair(args, height, width)?;
    read.extend(pair_files);
    check_outputs(&args.out, read)?;
    let metadata = [("source".to_string(), what.clone())];
    let export = Export {
        height,
        width,
        opset: args.opset,
        metadata: &metadata,
    };
    let name = args
        .out
        .file_stem()
        .map_or("mbs".into(), |s| s.to_string_lossy().into_owned());
    let notes = format!(
        "exported by mbs-tool export from {what}, {height}x{width}, opset {}",
        args.opset
    );
    eprintln!(
        "export: {what} -> ONNX at {height}x{width}, opset {}; checking through ONNX Runtime",
        args.opset
    );
    let probe = match args.fp16_probe {
        true => Probe::Every,
        false => Probe::Output,
    };
    let exported = export_checked(
        &network,
        &export,
        (&name, &notes),
        (&left, &right),
        &args.out,
        &args.tolerance,
        (probe, &args.runtime.options()?),
    )?;
    let report = exported
        .report
        .markdown(&format!("{name}: deployment report"));
    write(&args.out, &exported, &report)?;
    say_written(args, &exported.report.agreement);
    Ok(())
}

/// Tells how the export agreed and what it wrote.
fn say_written(args: &Args, a: &mbs_export::Agreement) {
    let (card, report) = companions(&args.out);
    eprintln!(
        "export: agrees with mbs on the check pair: largest {:.2e} px, mean {:.2e} px ({} of {} pixels); \
         mbs {:.2} s, ONNX Runtime {:.2} s",
        a.largest, a.mean, a.compared, a.pixels, a.mbs_seconds, a.onnx_seconds
    );
    eprintln!(
        "export: wrote {}, {} and {}\n  run it: mbs-tool predict --model {} --card {} ...",
        args.out.display(),
        card.display(),
        report.display(),
        args.out.display(),
        card.display()
    );
}

/// The run's network as safetensors.
fn safetensors(args: &Args) -> anyhow::Result<()> {
    let Some(run) = &args.run else {
        anyhow::bail!("--weights is for ONNX exports: a safetensors export reads a training run");
    };
    let out = safetensors_name(&args.out);
    refuse_special_target(&out).context("--out")?;
    let checkpoint = TrainedNetworks::open(run)?;
    let mut inputs = InputFiles::new();
    inputs.extend(checkpoint.files());
    inputs
        .refuse(&out)
        .context("--out would overwrite the checkpoint it exports")?;
    let (which, net) = trained_network(&checkpoint, args.student)?;
    net.export(&out)?;
    let backbone = checkpoint.network.backbone;
    eprintln!(
        "export: the {which} of {} ({backbone}, step {}) -> {}",
        checkpoint.dir.display(),
        checkpoint.steps,
        out.display()
    );
    Ok(())
}

/// `out` with the `.safetensors` extension the file format needs (the
/// official loaders and ONNX recipes go by it); says so when it differs.
fn safetensors_name(out: &Path) -> PathBuf {
    if out.extension().is_some_and(|ext| ext == "safetensors") {
        return out.to_path_buf();
    }
    let named = out.with_extension("safetensors");
    eprintln!(
        "export: --out {} is not a .safetensors name; writing {}",
        out.display(),
        named.display()
    );
    named
}

/// The teacher of `checkpoint` (with `student`, the student) on the CPU,
/// and which of the two it is.
fn trained_network(
    checkpoint: &TrainedNetworks,
    student: bool,
) -> anyhow::Result<(&'static str, StereoNetwork)> {
    let device = Device::flex();
    Ok(match student {
        true => ("student", checkpoint.student(&device)?),
        false => ("teacher", checkpoint.teacher(&device)?),
    })
}

/// The network an ONNX export reads, with `iters` iterations when given,
/// its description, and the files it was read from.
fn network(args: &Args) -> anyhow::Result<(StereoNetwork, String, Vec<PathBuf>)> {
    if let (Some(weights), Some(backbone)) = (&args.weights, args.backbone) {
        let mut config = NetworkConfig::with_overrides(backbone, &args.set)
            .context("the network settings (--set)")?;
        if let Some(iters) = args.iters {
            config = config.with_test_iters(iters).context("--iters")?;
        }
        let net = config.init(&Device::flex())?.with_weights(weights)?;
        let what = format!("{backbone} with {}", weights.display());
        return Ok((net, what, vec![weights.clone()]));
    }
    let run = args.run.as_ref().context("a training run or --weights")?;
    let mut checkpoint = TrainedNetworks::open(run)?;
    if let Some(iters) = args.iters {
        checkpoint.network = checkpoint
            .network
            .with_test_iters(iters)
            .context("--iters")?;
    }
    let (which, net) = trained_network(&checkpoint, args.student)?;
    let what = format!(
        "the {which} of {} ({}, step {})",
        checkpoint.dir.display(),
        checkpoint.network.backbone,
        checkpoint.steps
    );
    Ok((net, what, checkpoint.files().into()))
}

/// The check pair, fitted to `height` x `width`, and the files read.
fn check_pair(
    args: &Args,
    height: usize,
    width: usize,
) -> anyhow::Result<(mbs_core::RgbImage, mbs_core::RgbImage, Vec<PathBuf>)> {
    let (left, right, files) = match &args.check_pair {
        Some(paths) => {
            let read = |path: &PathBuf| -> anyhow::Result<mbs_core::RgbImage> {
                mbs_core::formats::rgb::read_rgb(path)
                    .with_context(|| format!("--check-pair {}", path.display()))
            };
            (read(&paths[0])?, read(&paths[1])?, paths.clone())
        }
        None => {
            let (left, right) = pair::built_in();
            (left, right, Vec::new())
        }
    };
    let (w, h) = (width as u32, height as u32);
    Ok((pair::fit(&left, w, h), pair::fit(&right, w, h), files))
}

/// Writes the export's three files (model last, so a model on disk always
/// has its card and report beside it).
fn write(out: &Path, exported: &mbs_export::Exported, report: &str) -> anyhow::Result<()> {
    let (card, report_path) = companions(out);
    let card_text = serde_json::to_string_pretty(&exported.card)? + "\n";
    write_bytes_atomic(&card, card_text.as_bytes()).with_context(|| card.display().to_string())?;
    write_bytes_atomic(&report_path, report.as_bytes())
        .with_context(|| report_path.display().to_string())?;
    write_bytes_atomic(out, &exported.model).with_context(|| out.display().to_string())?;
    Ok(())
}

/// Refuses an output (the model `out`, its card or its report) that is a
/// file the export reads or a special file, and a card or report that no
/// earlier export to `out` wrote.
fn check_outputs(out: &Path, read: Vec<PathBuf>) -> anyhow::Result<()> {
    let (card, report) = companions(out);
    let mut inputs = InputFiles::new();
    inputs.extend(read);
    for (output, name) in [(out, "--out"), (&card, "the card"), (&report, "the report")] {
        refuse_special_target(output).with_context(|| name.to_string())?;
        inputs
            .refuse(output)
            .with_context(|| format!("{name} would overwrite a file the export reads"))?;
    }
    refuse_foreign_companions(out, [&card, &report])
}

/// Refuses a card or report under the names beside `out` when there is no
/// model at `out`: such a file is not from an earlier export to that name
/// (which writes all three), and the export would replace it unasked.
fn refuse_foreign_companions(out: &Path, companions: [&Path; 2]) -> anyhow::Result<()> {
    if out.symlink_metadata().is_ok() {
        return Ok(());
    }
    for path in companions {
        if path.symlink_metadata().is_ok() {
            anyhow::bail!(
                "{}: exists but {} does not, so it is not from an earlier export to that name \
                 and would be replaced; move it away or choose another --out",
                path.display(),
                out.display()
            );
        }
    }
    Ok(())
}

/// The card and report files beside the model `out` (`NAME.card.json`,
/// `NAME.report.md`).
fn companions(out: &Path) -> (PathBuf, PathBuf) {
    (
        out.with_extension("card.json"),
        out.with_extension("report.md"),
    )
}
