//! `mbs-tool synth`: synthetic multi-camera street scenes with exact ground truth.

use std::path::PathBuf;

use clap::Parser;
use mbs_core::inputs::InputFiles;

use crate::cli::rig::RigArgs;
use mbs_synth::dataset::DatasetSpec;
use mbs_synth::{SceneConfig, Weather};

use crate::cli::batch::{self, Outcome};

/// Arguments of `synth`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool synth --out synth-data                       # 2 towns x 5 weathers x 4 frames, MBS20K rig
  mbs-tool synth --out small --width 160 --height 96 --focal 80 --frames 2 --weathers ClearNoon

Writes <out>/<Town>/<Weather>/<frame>/rgb_0.png … rgb_{N-1}.png, depth_0.png
(CARLA-encoded), gt/disp_k.pfm (exact disparity of camera k for a one-baseline
step; multiply by |t - k| for pair k:t), gt/occ_r_t.png (255 = pixel of r not
visible from t) and <out>/manifest.json. Deterministic for a given --seed;
finished frames are skipped when re-run. One process writes <out> at a time
(the shards of --shard share it); a file there under an output's name that
mbs did not write (<out>/.mbs-written lists what it did) is refused before
anything is written.")]
pub struct Args {
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Scenes per town.
    #[arg(long, default_value_t = 4, value_parser = crate::cli::values::count)]
    pub frames: usize,
    /// Town folder names, comma-separated; each gets its own scenes.
    #[arg(long, value_delimiter = ',', default_value = "Town01,Town10", value_parser = crate::cli::values::folder_name)]
    pub towns: Vec<String>,
    /// Weathers every scene is rendered under (ClearNight, ClearNoon,
    /// ClearSunset, CloudyNoon, MidRainyNoon).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "ClearNight,ClearNoon,ClearSunset,CloudyNoon,MidRainyNoon"
    )]
    pub weathers: Vec<Weather>,
    /// Towns whose samples form the test split.
    #[arg(long, value_delimiter = ',', default_value = "Town10", value_parser = crate::cli::values::folder_name)]
    pub test_towns: Vec<String>,
    #[command(flatten)]
    pub rig: RigArgs,
    /// Master seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Samples per pixel along each axis (anti-aliasing).
    #[arg(long, default_value_t = 2, value_parser = crate::cli::values::supersample)]
    pub supersample: u32,
    /// Depth beyond this many metres is invalid for disparity (recorded in the manifest).
    #[arg(long, default_value_t = 200.0, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub max_depth: f64,
    /// Do not record SHA-256 checksums in the manifest.
    #[arg(long)]
    pub no_checksums: bool,
    /// Sharding and worker threads.
    #[command(flatten)]
    pub batch: crate::cli::flags::Batch,
}

/// Runs `synth`.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.batch.threads.start()?;
    let rig = args.rig.rig();
    let spec = DatasetSpec {
        rig,
        towns: args.towns,
        weathers: args.weathers,
        frames: args.frames,
        seed: args.seed,
        test_towns: args.test_towns,
        scene: SceneConfig::centred_on(&rig),
        supersample: args.supersample,
        max_depth_m: args.max_depth,
        checksums: !args.no_checksums,
    };
    let frames = spec.frames();
    let frames = match args.batch.shard {
        Some(shard) => shard.select(frames),
        None => frames,
    };
    let manifest_path = args.out.join("manifest.json");
    let mut outputs: Vec<PathBuf> = frames
        .iter()
        .flat_map(|f| spec.frame_outputs(&args.out, f))
        .collect();
    if args.batch.shard.is_none() {
        outputs.push(manifest_path.clone());
    }
    let inputs = InputFiles::new();
    let _out = crate::cli::take_out(&args.out, args.batch.shard, "synth", &inputs, &outputs)?;
    let summary = batch::run(
        &frames,
        "scenes",
        |f| format!("{}/{:06}", spec.towns[f.town], f.index),
        |f| {
            if spec.is_complete(&args.out, f) {
                return Ok(Outcome::Skipped);
            }
            spec.write_frame(&args.out, f)?;
            Ok(Outcome::Done)
        },
    );
    summary.finish("synth", "scenes")?;
    if args.batch.shard.is_none() {
        spec.manifest(&args.out)?.save(&manifest_path)?;
        eprintln!(
            "synth: {} samples ({} scenes x {} weathers) -> {}",
            spec.towns.len() * spec.frames * spec.weathers.len(),
            spec.towns.len() * spec.frames,
            spec.weathers.len(),
            manifest_path.display()
        );
    }
    Ok(())
}
