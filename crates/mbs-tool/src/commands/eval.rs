//! `mbs-tool eval`: predicted disparities against ground truth — EPE,
//! Out-x and D1 over ALL, NOC and OCC pixels, per image, averaged per image
//! and pooled over pixels (conventions §6).

use std::path::{Path, PathBuf};

use crate::cli::pair::parse_pair;
use crate::cli::report_error::describe_item;
use anyhow::bail;
use clap::Parser;
use mbs_core::formats::{read_disparity, rgb};
use mbs_core::metrics::{MetricsReport, RegionSums, evaluate};
use mbs_core::{FloatImage, Side};
use mbs_dataset::ground_truth::{
    GroundTruthFile, GroundTruthPair, NocSource, find_map, kitti_pairs, manifest_pairs,
};
use mbs_dataset::{Manifest, Split};
use mbs_infer::{SgmConfig, StereoMatcher};

use crate::cli::source::StereoSourceArgs;
use rayon::prelude::*;
use serde_json::Value;

/// Arguments of `eval`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool eval pred/disp_0 --kitti /data/kitti2015/training
  mbs-tool eval pred/im2.pfm --gt teddy/disp2.png --gt-scale 4 --json
  mbs-tool eval pred --manifest mbs-demo/manifest.json --pair 0:1
  mbs-tool eval --checkpoint mbs-demo/run --manifest mbs-demo/train-data/manifest.json --split test
  mbs-tool eval --backbone raft-stereo --weights raftstereo-eth3d.pth --kitti /data/kitti2015/training
  mbs-tool eval --kitti /data/kitti2015/training --max-disparity 192   # the built-in matcher

Predictions are looked up as <PREDICTIONS>/<name>.pfm, .png (KITTI 16-bit)
or .exr, <name> being the GT file stem (KITTI) or the sample id (manifest).
Without PREDICTIONS, a disparity source predicts every pair: the built-in
matcher by default, the run's teacher with --checkpoint, an official or
exported network with --backbone and --weights (e.g. official RAFT-Stereo
weights), or an ONNX model with --model and --card.
A missing prediction value (+inf/NaN, 0 in PNGs) counts as an outlier for
Out-x and D1 and is left out of EPE; the density column says how many
pixels had one. ALL = valid GT; NOC = valid non-occluded GT (KITTI
disp_noc, a --noc mask, or the manifest's occlusion mask); OCC = ALL - NOC.")]
pub struct Args {
    /// A folder of predicted disparities, or one file with --gt [default:
    /// predict every pair with the disparity source].
    #[arg(conflicts_with_all = ["checkpoint", "weights", "model"])]
    pub predictions: Option<PathBuf>,
    /// What predicts the pairs when no PREDICTIONS are given.
    #[command(flatten)]
    pub source: StereoSourceArgs,
    /// A KITTI 2015 (disp_occ_0, disp_noc_0) or 2012 (disp_occ, disp_noc)
    /// training folder.
    #[arg(long, conflicts_with_all = ["gt", "manifest"])]
    pub kitti: Option<PathBuf>,
    /// Ground truth of a single prediction: PFM/EXR (+inf = unknown) or
    /// PNG/PGM (see --gt-scale).
    #[arg(long, requires = "predictions", conflicts_with = "manifest")]
    pub gt: Option<PathBuf>,
    /// Non-occluded mask for --gt (non-zero = non-occluded), e.g.
    /// Middlebury's nonocc.png.
    #[arg(long, requires = "gt")]
    pub noc: Option<PathBuf>,
    /// A dataset manifest whose samples have ground truth for --pair.
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// Camera pair of the manifest's ground truth, REFERENCE:TARGET.
    #[arg(long, default_value = "0:1", value_parser = parse_pair)]
    pub pair: (usize, usize),
    /// Only the manifest's samples of this split (train, val or test).
    #[arg(long, requires = "manifest", value_parser = parse_split)]
    pub split: Option<Split>,
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
    Pair {
        /// The reference view.
        reference: PathBuf,
        /// The target view.
        target: PathBuf,
        /// Which side of the reference the target lies on.
        side: Side,
    },
}

/// Runs `eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    crate::cli::set_threads(args.jobs)?;
    let predictions = args.predictions.as_deref();
    let items = if let (Some(gt), Some(predictions)) = (&args.gt, predictions) {
        let name = predictions.file_name().map_or_else(
            || predictions.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        vec![Item {
            prediction: Prediction::File(predictions.to_path_buf()),
            truth: GroundTruthFile {
                disparity: gt.clone(),
                scale: 1.0,
                noc: args.noc.clone().map(NocSource::Mask),
            },
            name,
        }]
    } else if let Some(dir) = &args.kitti {
        kitti_items(dir, predictions)?
    } else if let Some(manifest) = &args.manifest {
        manifest_items(manifest, args.pair, args.split, predictions)?
    } else {
        bail!("no ground truth: give --kitti DIR, --gt FILE or --manifest FILE");
    };
    let matcher = match predictions {
        Some(_) => None,
        None => Some(args.source.matcher(SgmConfig::default())?),
    };
    let results: Vec<anyhow::Result<RegionSums>> = items
        .par_iter()
        .map(|item| {
            let prediction = predict(item, matcher.as_deref())?;
            score(item, &prediction, args.gt_scale, &args.thresholds)
        })
        .collect();
    let mut scored = Vec::new();
    let mut failed = 0;
    for (item, result) in items.iter().zip(results) {
        match result {
            Ok(sums) => scored.push((item.name.clone(), sums)),
            Err(e) => {
                eprintln!("error: {}", describe_item(&item.name, &e));
                failed += 1;
            }
        }
    }
    if scored.is_empty() {
        bail!("no image could be scored (see above)");
    }
    let report = MetricsReport::new(scored);
    if args.json {
        println!("{:#}", report.json());
    } else {
        print!("{}", report.table(&args.thresholds));
    }
    if failed > 0 {
        bail!("{failed} of {} images failed (see above)", items.len());
    }
    Ok(())
}

/// A split by its manifest name (the names `Split` is serialised with).
fn parse_split(text: &str) -> Result<Split, String> {
    serde_json::from_value(Value::from(text))
        .map_err(|_| format!("`{text}` is not a split: train, val or test"))
}

/// The images of a KITTI training folder with their predictions (none:
/// the views, which must exist, for the disparity source).
pub fn kitti_items(dir: &Path, predictions: Option<&Path>) -> anyhow::Result<Vec<Item>> {
    let pairs = kitti_pairs(dir)?;
    if predictions.is_none() {
        mbs_dataset::kitti::KittiFolder::open(dir)?;
    }
    items(pairs, predictions)
}

/// The pairs with their prediction files, named by their ids.
fn items(pairs: Vec<GroundTruthPair>, predictions: Option<&Path>) -> anyhow::Result<Vec<Item>> {
    pairs
        .into_iter()
        .map(|pair| {
            let prediction = match predictions {
                Some(folder) => find_map(folder, &pair.id).map_or_else(
                    || Prediction::Missing(folder.to_path_buf()),
                    Prediction::File,
                ),
                None => Prediction::Pair {
                    reference: pair.reference,
                    target: pair.target,
                    side: pair.side,
                },
            };
            Ok(Item {
                name: pair.id,
                prediction,
                truth: pair.truth,
            })
        })
        .collect()
}

/// The samples of a manifest with ground truth for `pair`.
pub fn manifest_items(
    path: &Path,
    (reference, target): (usize, usize),
    split: Option<Split>,
    predictions: Option<&Path>,
) -> anyhow::Result<Vec<Item>> {
    let manifest = Manifest::load(path)?;
    let pairs = manifest_pairs(path, &manifest, &[(reference, target)], split)?;
    if pairs.is_empty() {
        bail!(
            "{}: no sample{} has ground truth for pair {reference}:{target}",
            path.display(),
            split.map_or(String::new(), |s| format!(" of the {s:?} split"))
        );
    }
    items(pairs, predictions)
}

/// Reads an item's prediction, or computes it with the disparity source;
/// with the file it came from (for messages).
fn predict(
    item: &Item,
    matcher: Option<&dyn StereoMatcher>,
) -> anyhow::Result<(FloatImage, PathBuf)> {
    match (&item.prediction, matcher) {
        (Prediction::File(path), _) => Ok((read_disparity(path, None)?, path.clone())),
        (Prediction::Missing(folder), _) => bail!(
            "no prediction {}.pfm, .png or .exr in {}",
            item.name,
            folder.display()
        ),
        (
            Prediction::Pair {
                reference,
                target,
                side,
            },
            Some(matcher),
        ) => {
            let reference_image = rgb::read_rgb(reference)?;
            let target_image = rgb::read_rgb(target)?;
            let disparity = matcher.predict_toward(&reference_image, &target_image, *side)?;
            Ok((disparity.disparity, reference.clone()))
        }
        (Prediction::Pair { reference, .. }, None) => {
            bail!(
                "{}: no prediction and no disparity source",
                reference.display()
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_parse_by_their_manifest_names() {
        assert_eq!(parse_split("train"), Ok(Split::Train));
        assert_eq!(parse_split("val"), Ok(Split::Val));
        assert_eq!(parse_split("test"), Ok(Split::Test));
        assert_eq!(
            parse_split("Test"),
            Err("`Test` is not a split: train, val or test".into())
        );
    }
}
