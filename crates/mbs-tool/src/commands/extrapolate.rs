//! `mbs-tool extrapolate`: a stereo pair -> two extra views, one baseline
//! further left and one further right (conventions §4), for one pair or a whole
//! KITTI folder.

use std::path::{Path, PathBuf};

use anyhow::bail;
use clap::Parser;
use mbs_core::inputs::InputFiles;
use mbs_dataset::kitti::KittiFrames;
use mbs_dataset::kitti::KittiVersion;
use mbs_dataset::pairs::PairSource;
use mbs_extrapolate::disparity::warping_sgm_config;
use mbs_extrapolate::{
    DisparitySource, Extrapolator, Frame, four_view_manifest, kitti_frames, pair_frame,
};

use crate::cli::batch::{self, Outcome};
use crate::cli::source::{StereoSource, StereoSourceArgs};
use crate::cli::synthesis::SynthesisArgs;

/// The manifest of the four-view samples, in the output folder.
const MANIFEST_FILE: &str = "manifest.json";

/// Arguments of `extrapolate`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool extrapolate --left L.png --right R.png --out out/
  mbs-tool extrapolate --left L.png --right R.png --left-disparity DL.pfm --out out/
  mbs-tool extrapolate --kitti kitti2015/training --left-disparity-dir monster/left
  mbs-tool extrapolate --kitti kitti2015/testing --model igev.onnx --card igev \\
      --inpaint onnx:lama_fp32.onnx --inpaint-card lama --device cuda
  mbs-tool extrapolate --kitti kitti2015/testing --checkpoint runs/s3 --device vulkan
  mbs-tool extrapolate --left L.png --right R.png --backbone igev \\
      --weights sceneflow.pth --out out/

Outputs: image_1 (new view left of the left view, at -B) and image_4 (right of
the right view, at +2B), mask_1 / mask_4 (255 = synthesised: holes and
dilated pixels) and the disparities used, disparity_2 (left view) and
disparity_3 (right view) as PFM. One pair: OUT/image_1.png, OUT/mask_1.png,
OUT/disparity_2.pfm... KITTI: sibling folders image_1/, image_4/, mask_1/,
mask_4/, disparity_2/, disparity_3/ beside image_2/ and image_3/, one file per
frame. The input pair is linked (or copied) into the output as image_2 and
image_3 (and KITTI's ground truth as disp_occ_0), so OUT/manifest.json names
only files inside OUT. Disparity files may be PFM, EXR or KITTI 16-bit PNG (value / 256,
0 = invalid); invalid pixels are filled from the background side. With only
one view's disparity, the other is derived by warping it (z-buffer) and
filling the disocclusions from the background side. Without files, the
disparities come from the disparity source: the built-in semi-global
matcher tuned for warping (8 paths, no uniqueness test, a 5x5 median) by
default, an ONNX model (--model, --card), a training run's teacher
(--checkpoint) or an official or exported network (--backbone, --weights);
the right view's by mirroring. Do not pass KITTI's ground truth (disp_occ_0, disp_noc_0) for data
meant for training without ground truth: the extrapolated views would carry
it into training (a warning says so). Finished frames are skipped, so an
interrupted run resumes where it stopped. An output that would replace an
input (a view, a disparity file, ground truth), or a file that mbs did not
write (OUT/.mbs-written lists those it did), is refused before anything is
written; one process writes an output folder at a time (the shards of
--shard share it).")]
pub struct Args {
    /// Left view of one pair (image_2 in KITTI).
    #[arg(long, requires = "right", required_unless_present = "kitti")]
    pub left: Option<PathBuf>,
    /// Right view of one pair (image_3 in KITTI).
    #[arg(long, requires = "left")]
    pub right: Option<PathBuf>,
    /// A KITTI split folder holding image_2/ and image_3/ (e.g. kitti2015/training).
    #[arg(long, conflicts_with_all = ["left", "left_disparity", "right_disparity"])]
    pub kitti: Option<PathBuf>,
    /// Output folder [required for one pair; KITTI: default the --kitti folder].
    #[arg(long, required_unless_present = "kitti")]
    pub out: Option<PathBuf>,
    /// Disparity of the left view (one pair).
    #[arg(long)]
    pub left_disparity: Option<PathBuf>,
    /// Disparity of the right view (one pair).
    #[arg(long)]
    pub right_disparity: Option<PathBuf>,
    /// Folder of disparities as this command writes them: one pair,
    /// disparity_2.* and/or disparity_3.*; KITTI, disparity_2/ and/or disparity_3/.
    #[arg(long, conflicts_with_all = ["left_disparity", "right_disparity"])]
    pub disparity_dir: Option<PathBuf>,
    /// KITTI: folder of left-view disparities named like image_2's files (e.g. disp_occ_0).
    #[arg(long, requires = "kitti", conflicts_with = "disparity_dir")]
    pub left_disparity_dir: Option<PathBuf>,
    /// KITTI: folder of right-view disparities named like image_3's files.
    #[arg(long, requires = "kitti", conflicts_with = "disparity_dir")]
    pub right_disparity_dir: Option<PathBuf>,
    /// Where the disparities of frames without disparity files come from.
    #[command(flatten)]
    pub source: StereoSourceArgs,
    /// How views are synthesised.
    #[command(flatten)]
    pub synthesis: SynthesisArgs,
    /// Also write a contact sheet per frame (preview/NAME.png): the four
    /// views, synthesised pixels tinted red, and the disparities used.
    #[arg(long)]
    pub preview: bool,
    /// Focal length in pixels, recorded in the manifest's rig (KITTI: about 721).
    #[arg(long, default_value_t = 721.5377, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub focal: f64,
    /// Baseline between the two input cameras in metres, recorded in the manifest (KITTI: 0.54).
    #[arg(long, default_value_t = 0.54, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub baseline: f64,
    /// Sharding and worker threads.
    #[command(flatten)]
    pub batch: crate::cli::flags::Batch,
}

/// Runs `extrapolate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.batch.threads.start()?;
    let (frames, out) = match &args.kitti {
        Some(root) => kitti_job(&args, root)?,
        None => single_pair_job(&args)?,
    };
    // Models and networks are opened before anything is written, so a bad
    // source leaves no output folder behind.
    let extrapolator = Extrapolator::new(
        args.synthesis.dilation(),
        args.synthesis.inpainter(&args.source.runtime)?,
    );
    let source = disparity_source(&args)?;
    let selected: Vec<&Frame> = match args.batch.shard {
        Some(shard) => shard.select(frames.iter().collect()),
        None => frames.iter().collect(),
    };
    let (inputs, outputs) = files(&args, &frames, &selected, &out);
    let settings = serde_json::json!({
        "source": args.source.settings()?,
        "synthesis": args.synthesis.provenance(),
    });
    let _out = crate::cli::take_out_settled(
        &out,
        args.batch.shard,
        "extrapolate",
        (&inputs, &outputs),
        &settings,
        false,
    )?;
    let summary = batch::run(
        &selected,
        "frames",
        |f| f.name.clone(),
        |f| {
            if f.is_done(args.preview) {
                return Ok(Outcome::Skipped);
            }
            f.process(&extrapolator, Some(&source), args.preview)?;
            Ok(Outcome::Done)
        },
    );
    let result = summary.finish("extrapolate", "frames");
    if args.batch.shard.is_none() {
        write_manifest(&args, &frames, &out)?;
    }
    result
}

/// Every file the frames are read from, and every file the `selected`
/// ones are written to in `out` (with the manifest, unless sharded).
fn files(
    args: &Args,
    frames: &[Frame],
    selected: &[&Frame],
    out: &Path,
) -> (InputFiles, Vec<PathBuf>) {
    let mut inputs = InputFiles::new();
    inputs.extend(frames.iter().flat_map(Frame::inputs));
    args.source.add_files_to(&mut inputs);
    inputs.extend(args.synthesis.model_file());
    let mut outputs: Vec<PathBuf> = selected
        .iter()
        .flat_map(|frame| frame.written(args.preview))
        .map(Path::to_path_buf)
        .collect();
    if args.batch.shard.is_none() {
        outputs.push(out.join(MANIFEST_FILE));
    }
    (inputs, outputs)
}

/// The frames of the KITTI folder `root` and the folder they go to (the
/// input's own unless `--out` says otherwise), with their disparities
/// from the folders given (a warning when one is KITTI's ground truth).
fn kitti_job(args: &Args, root: &Path) -> anyhow::Result<(Vec<Frame>, PathBuf)> {
    let out = args.out.clone().unwrap_or_else(|| root.to_path_buf());
    let dirs = match &args.disparity_dir {
        Some(dir) => (Some(dir.join("disparity_2")), Some(dir.join("disparity_3"))),
        None => (
            args.left_disparity_dir.clone(),
            args.right_disparity_dir.clone(),
        ),
    };
    for dir in [&dirs.0, &dirs.1].into_iter().flatten() {
        warn_if_ground_truth(dir);
    }
    let pairs = PairSource::Kitti {
        dir: root.to_path_buf(),
        frames: KittiFrames::All,
    }
    .pairs()?;
    let frames = kitti_frames(&pairs, &out, (dirs.0.as_deref(), dirs.1.as_deref()));
    Ok((frames, out))
}

/// The one frame of `--left` and `--right`, and `--out`.
fn single_pair_job(args: &Args) -> anyhow::Result<(Vec<Frame>, PathBuf)> {
    let (Some(left), Some(right), Some(out)) = (&args.left, &args.right, &args.out) else {
        bail!("give --left, --right and --out, or --kitti");
    };
    crate::cli::require_file(left, "left view")?;
    crate::cli::require_file(right, "right view")?;
    let pair = PairSource::Single {
        left: left.clone(),
        right: right.clone(),
    }
    .pairs()?
    .remove(0);
    let files = (args.left_disparity.clone(), args.right_disparity.clone());
    let frame = pair_frame(&pair, out, files, args.disparity_dir.as_deref())?;
    Ok((vec![frame], out.clone()))
}

/// Writes `out/manifest.json`, the four-view samples of the complete
/// `frames` (none: nothing is written, and it is said).
fn write_manifest(args: &Args, frames: &[Frame], out: &Path) -> anyhow::Result<()> {
    let done: Vec<_> = frames
        .iter()
        .filter(|f| f.is_done(false))
        .map(Frame::files)
        .collect();
    if done.is_empty() {
        eprintln!("extrapolate: no frame is complete, so no manifest was written");
        return Ok(());
    }
    let manifest = four_view_manifest(&done, out, args.focal, args.baseline)?;
    let path = out.join(MANIFEST_FILE);
    manifest.save(&path)?;
    eprintln!(
        "extrapolate: {} four-view samples -> {}",
        manifest.samples.len(),
        path.display()
    );
    Ok(())
}

/// Warns when a disparity folder is KITTI's ground truth: views warped with
/// it carry the ground truth into data meant for training without it.
fn warn_if_ground_truth(dir: &Path) {
    if KittiVersion::is_ground_truth_dir(dir) {
        eprintln!(
            "warning: {} is KITTI ground truth; views extrapolated with it leak the ground \
             truth into training data (use a matcher's disparities for unsupervised training)",
            dir.display()
        );
    }
}

/// The disparity source for frames without files: the built-in matcher
/// tuned for warping (estimating each pair's range unless
/// --max-disparity), or a network.
fn disparity_source(args: &Args) -> anyhow::Result<DisparitySource> {
    Ok(match args.source.open(warping_sgm_config(0))? {
        StereoSource::BuiltIn(config) => DisparitySource::BuiltIn(config),
        StereoSource::Network(matcher) => DisparitySource::Matcher(matcher),
    })
}
