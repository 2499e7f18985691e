//! `mbs-tool eval`: predicted disparities against ground truth under a
//! scoring protocol — by default mbs's `pixels`: EPE, Out-x and D1 over
//! ALL, NOC and OCC pixels, per image, averaged per image and pooled over
//! pixels (conventions §6); or a project's own rules (`--protocol`).

use std::path::{Path, PathBuf};

use anyhow::bail;
use clap::Parser;
use mbs_dataset::ground_truth::{GroundTruthFile, NocSource};
use mbs_dataset::pairs::PairSource;
use mbs_eval::{
    Dataset, FrameList, Item, Listing, Prediction, Predictor, Protocol, ProtocolReport,
    SourceScores, check_listed, items, rules_for,
};
use mbs_infer::SgmConfig;

use crate::cli::pairs::PairArgs;
use crate::cli::scoring::{score_with_bar, warn_unscored};
use crate::cli::source::StereoSourceArgs;

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
  mbs-tool eval pred --kitti /data/kitti2012/training --protocol kitti --frames train_all.txt

Predictions are looked up as <PREDICTIONS>/<name>.pfm, .png (KITTI 16-bit)
or .exr, <name> being the GT file stem (KITTI) or the sample id (manifest).
Without PREDICTIONS, a disparity source predicts every pair: the built-in
matcher by default, the run's teacher with --checkpoint, an official or
exported network with --backbone and --weights (e.g. official RAFT-Stereo
weights), or an ONNX model with --model and --card.
Under the default protocol, pixels, a missing prediction value (+inf/NaN,
0 in PNGs) counts as an outlier for Out-x and D1 and is left out of EPE;
the density column says how many pixels had one. ALL = valid GT; NOC =
valid non-occluded GT (KITTI disp_noc, Middlebury's and ETH3D's
mask0nocc.png, a --noc mask, or the manifest's occlusion mask); OCC = ALL -
NOC. DrivingStereo and SceneFlow have no occlusion masks: only ALL.
--protocol scores as a project does instead (its values below;
docs/evaluation.md); --frames FILE
scores only the frames it names. Frames without usable ground truth are
named in a warning. `mbs-tool benchmark` scores several benchmarks at
once.")]
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
    /// Out-x thresholds in pixels, comma-separated [default: 1,2,3 under
    /// pixels, the protocol's own otherwise].
    #[arg(long, value_delimiter = ',', value_parser = crate::cli::values::positive_f32, allow_hyphen_values = true)]
    pub thresholds: Vec<f32>,
    /// The scoring rules: pixels (mbs's, pooled over pixels), s3 (the S3
    /// paper's stereo_toolbox) or a project's own (docs/evaluation.md).
    #[arg(long, default_value = "pixels", value_parser = crate::cli::values::protocol())]
    pub protocol: Protocol,
    /// Score only the frames this file names, one a line (pair ids, e.g.
    /// KITTI 000000_10 or a Middlebury scene); blank lines and # comments
    /// are ignored.
    #[arg(long, value_name = "FILE", conflicts_with = "gt")]
    pub frames: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Worker threads.
    #[command(flatten)]
    pub threads: crate::cli::flags::Jobs,
}

/// Runs `eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.threads.start()?;
    let source = args.pairs.source()?;
    let dataset = source.as_ref().map_or(Dataset::Other, PairSource::dataset);
    let place = source
        .as_ref()
        .map_or_else(String::new, |s| s.place().display().to_string());
    let rules = rules_for(args.protocol, dataset, &args.thresholds)?;
    let (items, unscored) = list_items(&args, source)?;
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
    let predictor = matcher.as_ref().map(|m| m as &dyn Predictor);
    let (scored, summary) = score_with_bar(&items, predictor, args.gt_scale, &rules);
    if scored.images.is_empty() {
        bail!("no image could be scored (see above)");
    }
    let scores = SourceScores {
        report: Some(ProtocolReport::new(rules, scored.images)),
        failed: scored.failed,
        unscored: unscored.unscored,
    };
    if let (true, Some(json)) = (args.json, scores.json()) {
        println!("{json:#}");
    } else if let Some(report) = &scores.report {
        print!("{}", report.table());
    }
    warn_unscored(&place, &scores.unscored);
    summary.finish("eval", "images")
}

/// The items to score (only the `--frames` listed), and the source's
/// listing naming the frames left out for want of ground truth.
fn list_items(args: &Args, source: Option<PairSource>) -> anyhow::Result<(Vec<Item>, Listing)> {
    let predictions = args.predictions.as_deref();
    match (&args.gt, source) {
        (Some(gt), source) => {
            let truth = GroundTruthFile {
                disparity: gt.clone(),
                scale: 1.0,
                noc: args.noc.clone().map(NocSource::Mask),
            };
            let item = single_item(predictions, source, truth)?;
            Ok((vec![item], Listing::default()))
        }
        (None, Some(source)) => {
            let mut listing = Listing::of(&source)?;
            if let Some(path) = &args.frames {
                let list = FrameList::read(path)?;
                check_listed(&list, &[&listing], &source.place().display().to_string())?;
                listing = listing.keep(&list);
            }
            let pairs = std::mem::take(&mut listing.pairs);
            Ok((items(pairs, predictions), listing))
        }
        (None, None) => {
            bail!(
                "no ground truth: give a benchmark folder ({} DIR), --manifest FILE or --gt FILE",
                crate::cli::folders::flags_in_words::<crate::cli::folders::AnyOne>()
            )
        }
    }
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
            disparity_bound: None,
        });
    }
    match source {
        Some(source @ PairSource::Single { .. }) => {
            let pair = source.pairs()?.remove(0);
            Ok(Item {
                name: pair.id.clone(),
                disparity_bound: pair.disparity_bound,
                prediction: Prediction::Pair(pair),
                truth,
            })
        }
        _ => bail!("--gt scores one prediction file (PREDICTIONS) or one pair (--left, --right)"),
    }
}
