//! `mbs-tool decode-depth`: CARLA depth PNGs -> metric depth and disparity.

use std::path::PathBuf;

use anyhow::bail;
use clap::Parser;
use mbs_core::Rig;
use mbs_core::formats::{DepthFormat, DisparityFormat};
use mbs_core::inputs::InputFiles;
use mbs_dataset::Manifest;
use mbs_dataset::mbs20k::{
    DepthDecoding, DepthImage, depth_images_in_folder, depth_images_in_manifest,
};
use mbs_dataset::pairs::manifest_files;

use crate::cli::batch::{self, Outcome};
use crate::cli::pairs::parse_pair;

/// Arguments of `decode-depth`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool decode-depth /data/MBS20K --out /data/MBS20K-depth --all-pairs
  mbs-tool decode-depth mbs-demo/data/manifest.json --pairs 0:1,0:4 --disparity-format pfm
  mbs-tool decode-depth /data/MBS20K --shard $SLURM_ARRAY_TASK_ID/16
  srun -n 16 mbs-tool decode-depth /data/MBS20K --shard auto     # or mpirun -np 16

Outputs per frame: depth_0.exr (or .pfm, or depth_0_mm.png) and disp_0_T.png
(KITTI 16-bit, value/256) or disp_0_T.pfm for each requested pair 0:T.
Invalid pixels (depth beyond --max-depth) are +inf in EXR/PFM and 0 in PNGs.
Finished outputs are skipped, so an interrupted run resumes where it stopped.
One process writes the output folder (without --out, the input's folder) at
a time; an output that would replace an input or a file mbs did not write
there (FOLDER/.mbs-written lists what it did) is refused before anything is
written.")]
pub struct Args {
    /// An MBS20K folder (searched recursively for depth_0.png) or a manifest (.json).
    pub input: PathBuf,
    /// Output folder, mirroring the input's layout [default: beside each depth_0.png].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// File format of the depth maps.
    #[arg(long, value_enum, default_value_t = DepthFormat::Exr)]
    pub depth_format: DepthFormat,
    /// Also write disparity for these camera pairs, REFERENCE:TARGET, comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = parse_pair, conflicts_with = "all_pairs")]
    pub pairs: Vec<(usize, usize)>,
    /// Write disparity for the depth camera against every other camera.
    #[arg(long)]
    pub all_pairs: bool,
    /// File format of the disparity maps.
    #[arg(long, value_enum, default_value_t = DisparityFormat::Png16)]
    pub disparity_format: DisparityFormat,
    /// Depth beyond this many metres is invalid [default: the manifest's, else 200].
    #[arg(long, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub max_depth: Option<f64>,
    /// Focal length in pixels for folder input (MBS20K: 480).
    #[arg(long, default_value_t = 480.0, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub focal: f64,
    /// Baseline between neighbouring cameras in metres for folder input (MBS20K: 0.5).
    #[arg(long, default_value_t = 0.5, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub baseline: f64,
    /// Number of cameras for folder input (MBS20K: 5).
    #[arg(long, default_value_t = 5, value_parser = crate::cli::values::views)]
    pub views: usize,
    /// Sharding and worker threads.
    #[command(flatten)]
    pub batch: crate::cli::flags::Batch,
}

/// Runs `decode-depth`.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.batch.threads.start()?;
    let mut inputs = InputFiles::new();
    let (jobs, rig, camera, manifest_max) = input_images(&args, &mut inputs)?;
    let max_depth_m = args
        .max_depth
        .or(manifest_max)
        .unwrap_or(mbs_dataset::mbs20k::DEFAULT_MAX_DEPTH_M);
    if args.depth_format == DepthFormat::Png16 && max_depth_m > 65.535 {
        bail!(
            "--depth-format png16 stores millimetres in 16 bits (at most 65.535 m) but --max-depth is {max_depth_m} m: \
             pass --max-depth 65 or less, or use exr or pfm"
        );
    }
    let targets = requested_targets(&args.pairs, args.all_pairs, camera, rig.num_views)?;
    let plan = DepthDecoding {
        rig,
        camera,
        targets,
        max_depth_m: max_depth_m as f32,
        depth_format: args.depth_format,
        disparity_format: args.disparity_format,
    };
    let jobs = match args.batch.shard {
        Some(shard) => shard.select(jobs),
        None => jobs,
    };
    inputs.extend(jobs.iter().map(|j| &j.encoded));
    let outputs: Vec<PathBuf> = jobs.iter().flat_map(|j| plan.outputs(j)).collect();
    let root = match (&args.out, args.input.is_dir()) {
        (Some(out), _) => out.clone(),
        (None, true) => args.input.clone(),
        (None, false) => mbs_dataset::manifest::folder(&args.input),
    };
    let _out = crate::cli::take_out(&root, args.batch.shard, "decode-depth", &inputs, &outputs)?;
    let summary = batch::run(
        &jobs,
        "images",
        |j| j.encoded.display().to_string(),
        |j| {
            Ok(match plan.decode(j)? {
                true => Outcome::Done,
                false => Outcome::Skipped,
            })
        },
    );
    summary.finish("decode-depth", "images")
}

/// The depth images of the input (a folder, or a manifest's samples),
/// the rig that took them, the depth camera and the manifest's largest
/// depth; the input and, for a manifest, every file of its samples are
/// added to `inputs`.
fn input_images(
    args: &Args,
    inputs: &mut InputFiles,
) -> anyhow::Result<(Vec<DepthImage>, Rig, usize, Option<f64>)> {
    inputs.add(&args.input);
    if args.input.is_dir() {
        let rig = Rig {
            num_views: args.views,
            baseline_m: args.baseline,
            focal_px: args.focal,
            ..Rig::mbs20k()
        };
        let jobs = depth_images_in_folder(&args.input, args.out.as_deref())?;
        return Ok((jobs, rig, 0, None));
    }
    let manifest = Manifest::load(&args.input)?;
    inputs.extend(manifest_files(&args.input, &manifest));
    let depth = manifest.depth.as_ref();
    let camera = depth.map_or(0, |d| d.camera);
    let jobs = depth_images_in_manifest(&args.input, &manifest, args.out.as_deref())?;
    Ok((jobs, manifest.rig, camera, depth.map(|d| d.max_depth_m)))
}

fn requested_targets(
    pairs: &[(usize, usize)],
    all_pairs: bool,
    camera: usize,
    num_views: usize,
) -> anyhow::Result<Vec<usize>> {
    if all_pairs {
        return Ok((0..num_views).filter(|&t| t != camera).collect());
    }
    pairs
        .iter()
        .map(|&(r, t)| {
            if r != camera {
                bail!("pair {r}:{t}: depth exists for camera {camera} only, so the reference must be {camera}");
            }
            if t == r || t >= num_views {
                bail!("pair {r}:{t}: the target must be another camera of the {num_views}-camera rig");
            }
            Ok(t)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_must_start_at_the_depth_camera() {
        assert_eq!(
            requested_targets(&[(0, 1), (0, 4)], false, 0, 5).unwrap(),
            vec![1, 4]
        );
        assert_eq!(requested_targets(&[], true, 0, 3).unwrap(), vec![1, 2]);
        let err = requested_targets(&[(1, 2)], false, 0, 5)
            .unwrap_err()
            .to_string();
        assert!(err.contains("reference must be 0"), "{err}");
        let err = requested_targets(&[(0, 5)], false, 0, 5)
            .unwrap_err()
            .to_string();
        assert!(err.contains("5-camera rig"), "{err}");
    }
}
