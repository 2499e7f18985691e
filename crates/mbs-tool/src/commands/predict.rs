//! `mbs-tool predict`: disparity for rectified pairs from any disparity
//! source (the built-in semi-global matcher, an ONNX model, a trained
//! network).

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Parser, ValueEnum};
use mbs_core::Side;
use mbs_core::confine::join_confined;
use mbs_core::formats::{pfm, png16, rgb};
use mbs_dataset::Manifest;
use mbs_dataset::ground_truth::{check_cameras, sample_view};
use mbs_dataset::kitti::KittiFolder;
use mbs_infer::{SgmConfig, StereoMatcher};
use mbs_viz::colormap::{colorize_disparity, disparity_scale};

use crate::cli::batch::{self, Outcome};
use crate::cli::pair::parse_pair;
use crate::cli::shard::Shard;
use crate::cli::source::StereoSourceArgs;

/// Arguments of `predict`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool predict --left im2.png --right im6.png --max-disparity 64 --out pred --color
  mbs-tool predict --kitti /data/kitti2015/training --format png16 --out pred/disp_0
  mbs-tool predict --manifest mbs-demo/manifest.json --pair 2:1 --out pred
  mbs-tool predict --kitti DIR --model igev.onnx --card igev --device cuda --out pred
  mbs-tool predict --manifest data/manifest.json --pair 0:1 --checkpoint runs/demo --out pred
  mbs-tool predict --kitti DIR --backbone raft-stereo --weights raftstereo-sceneflow.pth --out pred

Outputs: <out>/<name>.pfm (+inf = invalid) or <out>/<name>.png (KITTI 16-bit,
value/256, 0 = invalid), where <name> is the left view's file stem (pairs and
KITTI) or the sample id (manifests); with --color also <name>_color.png.
With the built-in matcher, holes are filled from the background side, so
every pixel has a value; with --model, pixels the network gives a negative
disparity are invalid. Built-in cards: lama, migan, crestereo, hitnet,
raft-stereo, igev (see schemas/model-card.schema.json to write one).
Finished outputs are skipped, so an interrupted run resumes where it stopped.")]
pub struct Args {
    /// Left (reference) view of a single pair.
    #[arg(long, requires = "right", conflicts_with_all = ["kitti", "manifest"])]
    pub left: Option<PathBuf>,
    /// Right (target) view of a single pair.
    #[arg(long, requires = "left")]
    pub right: Option<PathBuf>,
    /// A KITTI 2015 (image_2, image_3) or 2012 (colored_0, colored_1)
    /// training or testing folder; its *_10.png frames are matched.
    #[arg(long, conflicts_with = "manifest")]
    pub kitti: Option<PathBuf>,
    /// A dataset manifest: every sample's --pair is matched.
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// Camera pair of manifest samples, REFERENCE:TARGET; a target left of
    /// the reference is handled by mirroring.
    #[arg(long, default_value = "0:1", value_parser = parse_pair)]
    pub pair: (usize, usize),
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// File format of the disparity maps.
    #[arg(long, value_enum, default_value_t = Format::Pfm)]
    pub format: Format,
    /// Also write a colour-mapped PNG of each disparity map.
    #[arg(long)]
    pub color: bool,
    /// Where the disparities come from.
    #[command(flatten)]
    pub source: StereoSourceArgs,
    /// Recompute outputs that already exist.
    #[arg(long)]
    pub overwrite: bool,
    /// Process only shard K of N (0-based), for cluster job arrays.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,
    /// Worker threads (0 = one per core).
    #[arg(long, default_value_t = 0, value_parser = crate::cli::values::jobs)]
    pub jobs: usize,
}

/// Disparity file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// PFM float32, +inf = invalid.
    Pfm,
    /// KITTI 16-bit PNG, value / 256 px, 0 = invalid.
    Png16,
}

impl Format {
    fn extension(self) -> &'static str {
        match self {
            Format::Pfm => "pfm",
            Format::Png16 => "png",
        }
    }
}

/// One pair to match and where its outputs go.
#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    /// The reference view (the disparity lives on its grid).
    pub reference: PathBuf,
    /// The target view.
    pub target: PathBuf,
    /// Which side of the reference the target camera lies on.
    pub side: Side,
    /// Output name without extension, relative to the output folder.
    pub name: String,
}

/// Runs `predict`.
pub fn run(args: Args) -> anyhow::Result<()> {
    crate::cli::set_threads(args.jobs)?;
    let jobs = if let (Some(left), Some(right)) = (&args.left, &args.right) {
        crate::cli::require_file(left, "left view")?;
        crate::cli::require_file(right, "right view")?;
        vec![Job {
            reference: left.clone(),
            target: right.clone(),
            side: Side::Right,
            name: file_stem(left)?,
        }]
    } else if let Some(dir) = &args.kitti {
        kitti_jobs(dir)?
    } else if let Some(manifest) = &args.manifest {
        manifest_jobs(manifest, args.pair)?
    } else {
        bail!("nothing to match: give --left and --right, --kitti DIR or --manifest FILE");
    };
    let jobs = match args.shard {
        Some(shard) => shard.select(jobs),
        None => jobs,
    };
    let matcher = args.source.matcher(SgmConfig::default())?;
    crate::cli::prepare_out(&args.out)?;
    let summary = batch::run(
        &jobs,
        "pairs",
        |j| j.reference.display().to_string(),
        |j| predict_one(&args, matcher.as_ref(), j),
    );
    summary.finish("predict", "pairs")
}

fn file_stem(path: &Path) -> anyhow::Result<String> {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .with_context(|| format!("{}: not a file name", path.display()))
}

/// The pairs of a KITTI folder: the `*_10` frames (those with ground
/// truth in training folders).
pub fn kitti_jobs(dir: &Path) -> anyhow::Result<Vec<Job>> {
    let folder = KittiFolder::open(dir)?;
    let jobs: Vec<Job> = folder
        .frames
        .iter()
        .filter(|f| f.ends_with("_10"))
        .map(|f| Job {
            reference: folder.left(f),
            target: folder.right(f),
            side: Side::Right,
            name: f.clone(),
        })
        .collect();
    if jobs.is_empty() {
        bail!(
            "{}: no *_10.png frames",
            dir.join(folder.version.view_dirs().0).display()
        );
    }
    Ok(jobs)
}

/// The `(reference, target)` pair of every sample of a manifest.
pub fn manifest_jobs(path: &Path, (reference, target): (usize, usize)) -> anyhow::Result<Vec<Job>> {
    let manifest = Manifest::load(path)?;
    check_cameras(path, &manifest, &[(reference, target)])?;
    manifest
        .samples
        .iter()
        .map(|s| {
            Ok(Job {
                reference: sample_view(path, s, reference)?,
                target: sample_view(path, s, target)?,
                side: if target < reference {
                    Side::Left
                } else {
                    Side::Right
                },
                name: s.id.clone(),
            })
        })
        .collect()
}

fn predict_one(args: &Args, matcher: &dyn StereoMatcher, job: &Job) -> anyhow::Result<Outcome> {
    let out = join_confined(
        &args.out,
        &format!("{}.{}", job.name, args.format.extension()),
    )?;
    let color = join_confined(&args.out, &format!("{}_color.png", job.name))?;
    if !args.overwrite && out.exists() && (!args.color || color.exists()) {
        return Ok(Outcome::Skipped);
    }
    let reference = rgb::read_rgb(&job.reference)?;
    let target = rgb::read_rgb(&job.target)?;
    let prediction = matcher.predict_toward(&reference, &target, job.side)?;
    let disparity = &prediction.disparity;
    match args.format {
        Format::Pfm => pfm::write_pfm_grey(&out, disparity, pfm::Endian::Little)?,
        Format::Png16 => png16::write_kitti_disparity(&out, disparity)?,
    }
    if args.color {
        let top = match args.source.max_disparity.unwrap_or(0) {
            0 => disparity_scale([disparity]),
            n => n as f32,
        };
        rgb::write_rgb_png(&color, &colorize_disparity(disparity, top))?;
    }
    Ok(Outcome::Done)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kitti_folders_need_both_views() {
        let dir = tempfile::tempdir().unwrap();
        let err = kitti_jobs(dir.path()).unwrap_err().to_string();
        assert!(err.contains("not a KITTI folder"), "{err}");
        std::fs::create_dir_all(dir.path().join("colored_0")).unwrap();
        std::fs::create_dir_all(dir.path().join("colored_1")).unwrap();
        std::fs::write(dir.path().join("colored_0/000001_10.png"), b"").unwrap();
        std::fs::write(dir.path().join("colored_0/000001_11.png"), b"").unwrap();
        let jobs = kitti_jobs(dir.path()).unwrap();
        assert_eq!(jobs.len(), 1);
        assert_eq!(jobs[0].name, "000001_10");
        assert_eq!(jobs[0].target, dir.path().join("colored_1/000001_10.png"));
    }
}
