//! `mbs-tool predict`: disparity for rectified pairs from any disparity
//! source (the built-in semi-global matcher, an ONNX model, a trained
//! network).

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::bail;
use clap::Parser;
use mbs_core::confine::join_confined;
use mbs_core::formats::{DisparityFormat, rgb};
use mbs_dataset::StereoPair;
use mbs_infer::SgmConfig;
use mbs_viz::colormap::{colorize_disparity, disparity_scale};

use crate::cli::batch::{self, Outcome};
use crate::cli::pairs::PairArgs;
use crate::cli::source::{PairMatcher, StereoSourceArgs};

/// Arguments of `predict`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool predict --left im2.png --right im6.png --max-disparity 64 --out pred --color
  mbs-tool predict --kitti /data/kitti2015/training --format png16 --out pred/disp_0
  mbs-tool predict --manifest mbs-demo/data/manifest.json --pair 2:1 --out pred
  mbs-tool predict --kitti DIR --model igev.onnx --card igev --device cuda --out pred
  mbs-tool predict --manifest data/manifest.json --pair 0:1 --checkpoint runs/demo --out pred
  mbs-tool predict --kitti DIR --backbone raft-stereo --weights raftstereo-sceneflow.pth --out pred
  mbs-tool predict --sceneflow /data/flyingthings3d/frames_finalpass/TEST --out pred

Outputs: <out>/<name>.pfm (+inf = invalid) or <out>/<name>.png (KITTI 16-bit,
value/256, 0 = invalid), where <name> is the left view's file stem (pairs and
KITTI) or the sample id (manifests); with --color also <name>_color.png.
With the built-in matcher, holes are filled from the background side, so
every pixel has a value; with --model, pixels the network gives a negative
disparity are invalid. Built-in cards: lama, migan, crestereo, hitnet,
raft-stereo, igev (see schemas/model-card.schema.json to write one).
Finished outputs are skipped, so an interrupted run resumes where it stopped.
One process writes an output folder at a time (the shards of --shard share
it). An output that would replace a file the command reads (a view, ground
truth, any file of a manifest's samples), or a file in --out that mbs did
not write (OUT/.mbs-written lists those it did), is refused before anything
is written, whatever the flags: --overwrite replaces mbs's own outputs only.")]
pub struct Args {
    /// The pairs to match.
    #[command(flatten)]
    pub pairs: PairArgs,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// File format of the disparity maps.
    #[arg(long, value_enum, default_value_t = DisparityFormat::Pfm)]
    pub format: DisparityFormat,
    /// Also write a colour-mapped PNG of each disparity map.
    #[arg(long)]
    pub color: bool,
    /// Where the disparities come from.
    #[command(flatten)]
    pub source: StereoSourceArgs,
    /// Whether earlier outputs are recomputed.
    #[command(flatten)]
    pub overwrite: crate::cli::flags::Overwrite,
    /// Sharding and worker threads.
    #[command(flatten)]
    pub batch: crate::cli::flags::Batch,
}

/// Runs `predict`.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.batch.threads.start()?;
    let Some(source) = args.pairs.source()? else {
        bail!(
            "nothing to match: give --left and --right, a benchmark folder (--kitti, \
             --middlebury, --eth3d, --drivingstereo, --sceneflow DIR) or --manifest FILE"
        );
    };
    let pairs = source.pairs()?;
    let mut inputs = source.input_files(&pairs)?;
    args.source.add_files_to(&mut inputs);
    let pairs = match args.batch.shard {
        Some(shard) => shard.select(pairs),
        None => pairs,
    };
    let outputs = every_output(&args, &pairs)?;
    args.source.refuse_unused_device()?;
    let matcher = args.source.matcher(SgmConfig::default())?;
    let settings = serde_json::json!({ "source": args.source.settings()?, "color": args.color });
    let _out = crate::cli::take_out_settled(
        &args.out,
        args.batch.shard,
        "predict",
        (&inputs, &outputs),
        &settings,
        args.overwrite.overwrite,
    )?;
    let summary = batch::run(
        &pairs,
        "pairs",
        |p| p.reference.display().to_string(),
        |p| predict_one(&args, &matcher, p),
    );
    summary.finish("predict", "pairs")
}

/// A pair's disparity file and colour picture under `--out`.
fn outputs(args: &Args, pair: &StereoPair) -> anyhow::Result<(PathBuf, PathBuf)> {
    let out = join_confined(
        &args.out,
        &format!("{}.{}", pair.id, args.format.extension()),
    )?;
    let color = join_confined(&args.out, &format!("{}_color.png", pair.id))?;
    Ok((out, color))
}

/// Every file the pairs are written to; two pairs sharing one is an error.
fn every_output(args: &Args, pairs: &[StereoPair]) -> anyhow::Result<Vec<PathBuf>> {
    let mut written_by: BTreeMap<PathBuf, &str> = BTreeMap::new();
    for pair in pairs {
        let (out, color) = outputs(args, pair)?;
        let files = if args.color {
            vec![out, color]
        } else {
            vec![out]
        };
        for file in files {
            if let Some(first) = written_by.insert(file.clone(), &pair.id) {
                bail!(
                    "{}: pairs {first} and {} would both be written there",
                    file.display(),
                    pair.id
                );
            }
        }
    }
    Ok(written_by.into_keys().collect())
}

fn predict_one(args: &Args, matcher: &PairMatcher, pair: &StereoPair) -> anyhow::Result<Outcome> {
    let (out, color) = outputs(args, pair)?;
    if !args.overwrite.overwrite && out.exists() && (!args.color || color.exists()) {
        return Ok(Outcome::Skipped);
    }
    let reference = rgb::read_rgb(&pair.reference)?;
    let target = rgb::read_rgb(&pair.target)?;
    let prediction = matcher.predict(pair, &reference, &target)?;
    let disparity = &prediction.disparity;
    args.format.write(&out, disparity)?;
    if args.color {
        let top = match args
            .source
            .max_disparity
            .or(pair.disparity_bound)
            .unwrap_or(0)
        {
            0 => disparity_scale([disparity]),
            n => n as f32,
        };
        rgb::write_rgb_png(&color, &colorize_disparity(disparity, top))?;
    }
    Ok(Outcome::Done)
}
