//! `mbs-tool export`: a training run's network as safetensors under the
//! official implementation's keys, for the official PyTorch code and its
//! ONNX export recipes (`tools/onnx/EXPORT.md`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use burn::tensor::Device;
use clap::Parser;
use mbs_core::atomic::refuse_special_target;
use mbs_core::inputs::InputFiles;
use mbs_nets::checkpoint::TrainedNetworks;

/// Arguments of `export`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool export runs/raft --out teacher.safetensors
  mbs-tool export runs/raft/checkpoints/step-0005000 --student --out student.safetensors

RAFT-Stereo weights carry the official keys (princeton-vl/RAFT-Stereo), so
the official code loads them unchanged:

  from safetensors.torch import load_file
  model = RAFTStereo(args)        # the run's network.raft_stereo settings
  model.load_state_dict(load_file('teacher.safetensors'))

The compact network has no official implementation; its file holds mbs's
own parameter names, which `--init` and `--weights` read back.")]
pub struct Args {
    /// A training run (its newest checkpoint) or a checkpoints/step-N folder.
    pub run: PathBuf,
    /// The safetensors file to write.
    #[arg(long, value_name = "FILE.safetensors")]
    pub out: PathBuf,
    /// Export the student instead of the teacher.
    #[arg(long)]
    pub student: bool,
}

/// Runs `export`.
pub fn run(args: Args) -> anyhow::Result<()> {
    // The name as given first: a device such as /dev/null is refused as
    // itself, never written beside as /dev/null.safetensors.
    refuse_special_target(&args.out).context("--out")?;
    let out = safetensors_name(&args.out);
    refuse_special_target(&out).context("--out")?;
    let checkpoint = TrainedNetworks::open(&args.run)?;
    let mut inputs = InputFiles::new();
    inputs.extend(checkpoint.files());
    inputs
        .refuse(&out)
        .context("--out would overwrite the checkpoint it exports")?;
    let device = Device::flex();
    let (which, net) = if args.student {
        ("student", checkpoint.student(&device)?)
    } else {
        ("teacher", checkpoint.teacher(&device)?)
    };
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
