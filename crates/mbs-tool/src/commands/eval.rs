//! `mbs-tool eval`: predicted disparities against ground truth — EPE,
//! Out-x and D1 over ALL, NOC and OCC pixels, per image, averaged per image
//! and pooled over pixels (conventions §6).

use std::path::{Path, PathBuf};

use anyhow::bail;
use clap::Parser;
use mbs_core::FloatImage;
use mbs_core::formats::{read_disparity, rgb};
use mbs_core::metrics::{MetricsReport, RegionSums, evaluate};
use mbs_dataset::ground_truth::{GroundTruthFile, NocSource, find_map};
use mbs_dataset::pairs::{PairSource, StereoPair};
use mbs_infer::SgmConfig;

use crate::cli::batch;
use crate::cli::pairs::PairArgs;
use crate::cli::source::{PairMatcher, StereoSourceArgs};

/// Arguments of `eval`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool eval pred/disp_0 --kitti /data/kitti2015/training
  mbs-tool eval pred/im2.pfm --gt teddy/disp2.png --gt-scale 4 --json
  mbs-tool eval pred --manifest mbs-demo/data/manifest.json --pair 0:1
  mbs-tool eval --checkpoint mbs-demo/run --manifest mbs-demo/train-data/manifest.json --split test
  mbs-tool eval --backbone raft-stereo --weights raftstereo-eth3d.pth --kitti /data/kitti2015/training
  mbs-tool eval --kitti /data/kitti2015/training --max-disparity 192   # the built-in matcher
  mbs-tool eval pred --middlebury /data/MiddEval3/trainingH
  mbs-tool eval pred --drivingstereo /data/DrivingStereo/rainy
  mbs-tool eval --left im2.png --right im6.png --gt disp2.png --gt-scale 4 --max-disparity 64

Predictions are looked up as <PREDICTIONS>/<name>.pfm, .png (KITTI 16-bit)
or .exr, <name> being the GT file stem (KITTI) or the sample id (manifest).
Without PREDICTIONS, a disparity source predicts every pair: the built-in
matcher by default, the run's teacher with --checkpoint, an official or
exported network with --backbone and --weights (e.g. official RAFT-Stereo
weights), or an ONNX model with --model and --card.
A missing prediction value (+inf/NaN, 0 in PNGs) counts as an outlier for
Out-x and D1 and is left out of EPE; the density column says how many
pixels had one. ALL = valid GT; NOC = valid non-occluded GT (KITTI
disp_noc, Middlebury's and ETH3D's mask0nocc.png, a --noc mask, or the
manifest's occlusion mask); OCC = ALL - NOC. DrivingStereo and SceneFlow
have no occlusion masks: only ALL. `mbs-tool benchmark` scores several
benchmarks at once with each one's customary metric.")]
pub struct Args {
    /// A folder of predicted disparities, or one file with --gt [default:
    /// predict every pair with the disparity source].
    #[arg(conflicts_with_all = ["checkpoint", "weights", "model"])]
    pub predictions: Option<PathBuf>,
    /// What predicts the pairs when no PREDICTIONS are given.
    #[command(flatten)]
    pub source: StereoSourceArgs,
    /// The pairs with ground truth.
    #[command(flatten)]
    pub pairs: PairArgs,
    /// Ground truth of one prediction file (PREDICTIONS) or of one pair
    /// (--left, --right): PFM/EXR (+inf = unknown) or PNG/PGM (see
    /// --gt-scale).
    #[arg(long, conflicts_with_all = ["kitti", "manifest"])]
    pub gt: Option<PathBuf>,
    /// Non-occluded mask for --gt (non-zero = non-occluded), e.g.
    /// Middlebury's nonocc.png.
    #[arg(long, requires = "gt")]
    pub noc: Option<PathBuf>,
    /// GT PNG/PGM codes per pixel of disparity [default: 256 for 16-bit
    /// images (KITTI), 1 for 8-bit ones; Middlebury 2003 quarter size: 4,
    /// Tsukuba: 16].
    #[arg(long, value_parser = crate::cli::values::positive_f32, allow_negative_numbers = true)]
    pub gt_scale: Option<f32>,
    /// Out-x thresholds in pixels, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2,3", value_parser = crate::cli::values::positive_f32, allow_hyphen_values = true)]
    pub thresholds: Vec<f32>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Worker threads (0 = one per core).
    #[arg(long, default_value_t = 0, value_parser = crate::cli::values::jobs)]
    pub jobs: usize,
}

/// One image to score.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    /// Name in the table.
    pub name: String,
    /// Where the prediction comes from.
    pub prediction: Prediction,
    /// The ground truth it is scored against.
    pub truth: GroundTruthFile,
}

/// Where a prediction comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Prediction {
    /// A disparity file.
    File(PathBuf),
    /// No file named after the item in this predictions folder: the item
    /// is reported as failed and the others are scored.
    Missing(PathBuf),
    /// A pair the disparity source predicts.
    Pair(StereoPair),
}

/// Runs `eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    crate::cli::set_threads(args.jobs)?;
    let predictions = args.predictions.as_deref();
    let items = match (&args.gt, args.pairs.source()?) {
        (Some(gt), source) => {
            let truth = GroundTruthFile {
                disparity: gt.clone(),
                scale: 1.0,
                noc: args.noc.clone().map(NocSource::Mask),
            };
            vec![single_item(predictions, source, truth)?]
        }
        (None, Some(source)) => items(source.scored_pairs()?, predictions),
        (None, None) => {
            bail!(
                "no ground truth: give a benchmark folder (--kitti, --middlebury, --eth3d, \
                 --drivingstereo, --sceneflow DIR), --manifest FILE or --gt FILE"
            )
        }
    };
    let matcher = match items
        .iter()
        .any(|i| matches!(i.prediction, Prediction::Pair(_)))
    {
        true => {
            args.source.refuse_unused_device()?;
            Some(args.source.matcher(SgmConfig::default())?)
        }
        false => None,
    };
    let (scored, summary) = score_all(&items, matcher.as_ref(), args.gt_scale, &args.thresholds);
    if scored.is_empty() {
        bail!("no image could be scored (see above)");
    }
    let report = MetricsReport::new(scored);
    if args.json {
        println!("{:#}", report.json());
    } else {
        print!("{}", report.table(&args.thresholds));
    }
    summary.finish("eval", "images")
}

/// Scores every item with a progress bar: its prediction (read, or
/// computed by `matcher`) against its ground truth at `thresholds`. An
/// item that fails is reported on stderr and counted in the summary; the
/// others are scored.
pub fn score_all(
    items: &[Item],
    matcher: Option<&PairMatcher>,
    gt_scale: Option<f32>,
    thresholds: &[f32],
) -> (Vec<(String, RegionSums)>, batch::Summary) {
    let (results, summary) = batch::map(
        items,
        "images",
        |item| item.name.clone(),
        |item| {
            let prediction = predict(item, matcher)?;
            score(item, &prediction, gt_scale, thresholds)
        },
    );
    let scored = items
        .iter()
        .zip(results)
        .filter_map(|(item, sums)| Some((item.name.clone(), sums?)))
        .collect();
    (scored, summary)
}

/// The one item `--gt` scores: the prediction file, or else the one pair
/// (--left, --right) predicted by the disparity source.
fn single_item(
    predictions: Option<&Path>,
    source: Option<PairSource>,
    truth: GroundTruthFile,
) -> anyhow::Result<Item> {
    if let Some(file) = predictions {
        let name = file.file_name().map_or_else(
            || file.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        return Ok(Item {
            name,
            prediction: Prediction::File(file.to_path_buf()),
            truth,
        });
    }
    match source {
        Some(source @ PairSource::Single { .. }) => {
            let pair = source.pairs()?.remove(0);
            Ok(Item {
                name: pair.id.clone(),
                prediction: Prediction::Pair(pair),
                truth,
            })
        }
        _ => bail!("--gt scores one prediction file (PREDICTIONS) or one pair (--left, --right)"),
    }
}

/// The pairs with ground truth, with their prediction files in the
/// `predictions` folder (none: predicted by the disparity source).
pub fn items(pairs: Vec<StereoPair>, predictions: Option<&Path>) -> Vec<Item> {
    pairs
        .into_iter()
        .filter_map(|mut pair| {
            let truth = pair.truth.take()?;
            let name = pair.id.clone();
            let prediction = match predictions {
                Some(folder) => find_map(folder, &name).map_or_else(
                    || Prediction::Missing(folder.to_path_buf()),
                    Prediction::File,
                ),
                None => Prediction::Pair(pair),
            };
            Some(Item {
                name,
                prediction,
                truth,
            })
        })
        .collect()
}

/// Reads an item's prediction, or computes it with the disparity source;
/// with the file it came from (for messages).
fn predict(item: &Item, matcher: Option<&PairMatcher>) -> anyhow::Result<(FloatImage, PathBuf)> {
    match (&item.prediction, matcher) {
        (Prediction::File(path), _) => Ok((read_disparity(path, None)?, path.clone())),
        (Prediction::Missing(folder), _) => bail!(
            "no prediction {}.pfm, .png or .exr in {}",
            item.name,
            folder.display()
        ),
        (Prediction::Pair(pair), Some(matcher)) => {
            let reference = rgb::read_rgb(&pair.reference)?;
            let target = rgb::read_rgb(&pair.target)?;
            let disparity = matcher.predict(pair, &reference, &target)?;
            Ok((disparity.disparity, pair.reference.clone()))
        }
        (Prediction::Pair(pair), None) => {
            bail!(
                "{}: no prediction and no disparity source",
                pair.reference.display()
            )
        }
    }
}

fn score(
    item: &Item,
    (prediction, source): &(FloatImage, PathBuf),
    gt_scale: Option<f32>,
    thresholds: &[f32],
) -> anyhow::Result<RegionSums> {
    let gt = item.truth.load(gt_scale)?;
    check_size(prediction, &gt.disparity, source, &item.truth.disparity)?;
    if !gt.disparity.iter().any(|d| d.is_finite()) {
        bail!(
            "{}: the ground truth has no valid pixel: nothing to score",
            item.truth.disparity.display()
        );
    }
    Ok(evaluate(
        prediction,
        &gt.disparity,
        gt.noc.as_ref(),
        thresholds,
    )?)
}

fn check_size(
    prediction: &FloatImage,
    gt: &FloatImage,
    path: &Path,
    gt_path: &Path,
) -> anyhow::Result<()> {
    if prediction.dimensions() != gt.dimensions() {
        bail!(
            "{}: prediction is {:?} but the ground truth {} is {:?} (width, height)",
            path.display(),
            prediction.dimensions(),
            gt_path.display(),
            gt.dimensions()
        );
    }
    Ok(())
}
