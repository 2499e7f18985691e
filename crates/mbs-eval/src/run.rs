//! The scoring run: the images of a source (each with its prediction, read
//! from a folder or computed by a [`Predictor`], and its ground truth),
//! scored in parallel under one protocol's rules, with a progress callback
//! after each image. An image that fails is reported and the others are
//! scored.

use std::error::Error;
use std::path::{Path, PathBuf};

use mbs_core::FloatImage;
use mbs_core::formats::read_disparity;
use mbs_dataset::StereoPair;
use mbs_dataset::ground_truth::{GroundTruth, GroundTruthFile, find_map};
use mbs_dataset::pairs::PairSource;
use rayon::prelude::*;
use serde_json::{Value, json};

use crate::error::EvalError;
use crate::frames::FrameList;
use crate::listing::{Listing, check_listed};
use crate::protocol::{ProtocolError, Rules};
use crate::protocol_report::ProtocolReport;
use crate::score::{Frame, ImageScore};

/// One image to score.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    /// Name in reports.
    pub name: String,
    /// Where the prediction comes from.
    pub prediction: Prediction,
    /// The ground truth it is scored against.
    pub truth: GroundTruthFile,
    /// The pair's disparity bound (Middlebury's `ndisp`), if stated.
    pub disparity_bound: Option<u32>,
}

/// Where a prediction comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Prediction {
    /// A disparity file.
    File(PathBuf),
    /// No file named after the item in this predictions folder: the item
    /// fails and the others are scored.
    Missing(PathBuf),
    /// A pair the [`Predictor`] predicts.
    Pair(StereoPair),
}

/// What predicts the disparity of a pair (a matcher, a network).
pub trait Predictor: Sync {
    /// The disparity of `pair` on its reference view's grid.
    fn predict(&self, pair: &StereoPair) -> Result<FloatImage, Box<dyn Error + Send + Sync>>;
}

/// What the run reports after each image.
#[derive(Debug, Clone, Copy)]
pub enum Progress<'a> {
    /// The image was scored.
    Scored {
        /// The image's name.
        name: &'a str,
    },
    /// The image failed; the others are scored.
    Failed {
        /// The image's name.
        name: &'a str,
        /// Why.
        error: &'a EvalError,
    },
}

/// The images a run scored and those that failed, in item order.
#[derive(Debug, Default)]
pub struct Scored {
    /// Each scored image's name and score.
    pub images: Vec<(String, ImageScore)>,
    /// Each failed image's name and error.
    pub failed: Vec<(String, EvalError)>,
}

/// The pairs with ground truth, with their prediction files in the
/// `predictions` folder (none: predicted by a [`Predictor`]).
pub fn items(pairs: Vec<StereoPair>, predictions: Option<&Path>) -> Vec<Item> {
    pairs
        .into_iter()
        .filter_map(|mut pair| {
            let truth = pair.truth.take()?;
            let name = pair.id.clone();
            let disparity_bound = pair.disparity_bound;
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
                disparity_bound,
            })
        })
        .collect()
}

/// Scores `prediction` (from `prediction_path`, for messages) against the
/// ground truth `truth` (read from `truth_path`) under `rules`; a ground
/// truth without a finite pixel is an error.
pub fn score_truth(
    truth: &GroundTruth,
    truth_path: &Path,
    prediction: &FloatImage,
    prediction_path: &Path,
    disparity_bound: Option<u32>,
    rules: &Rules,
) -> Result<ImageScore, EvalError> {
    if !truth.disparity.iter().any(|d| d.is_finite()) {
        return Err(EvalError::NoValidPixel(truth_path.to_path_buf()));
    }
    let frame = Frame {
        prediction,
        gt: &truth.disparity,
        noc: truth.noc.as_ref(),
        disparity_bound,
    };
    rules.score(&frame).map_err(|error| match error {
        ProtocolError::NeedsMask { .. } => EvalError::NeedsMask {
            gt: truth_path.to_path_buf(),
            error,
        },
        _ => EvalError::Rules {
            prediction: prediction_path.to_path_buf(),
            gt: truth_path.to_path_buf(),
            error,
        },
    })
}

/// Scores every item under `rules`, in parallel, keeping the items'
/// order: its prediction (read, or computed by `predictor`) against its
/// ground truth (integer files read at `gt_scale` codes per pixel).
/// `progress` hears of each item once, when it is scored or has failed.
pub fn score_items(
    items: &[Item],
    predictor: Option<&dyn Predictor>,
    gt_scale: Option<f32>,
    rules: &Rules,
    progress: &(dyn Fn(Progress<'_>) + Sync),
) -> Scored {
    let results: Vec<Result<ImageScore, EvalError>> = items
        .par_iter()
        .map(|item| {
            let result = score_item(item, predictor, gt_scale, rules);
            progress(match &result {
                Ok(_) => Progress::Scored { name: &item.name },
                Err(error) => Progress::Failed {
                    name: &item.name,
                    error,
                },
            });
            result
        })
        .collect();
    let mut scored = Scored::default();
    for (item, result) in items.iter().zip(results) {
        match result {
            Ok(score) => scored.images.push((item.name.clone(), score)),
            Err(error) => scored.failed.push((item.name.clone(), error)),
        }
    }
    scored
}

/// One item's prediction scored against its ground truth.
fn score_item(
    item: &Item,
    predictor: Option<&dyn Predictor>,
    gt_scale: Option<f32>,
    rules: &Rules,
) -> Result<ImageScore, EvalError> {
    let (prediction, prediction_path) = predict(item, predictor)?;
    let truth = item.truth.load(gt_scale)?;
    score_truth(
        &truth,
        &item.truth.disparity,
        &prediction,
        &prediction_path,
        item.disparity_bound,
        rules,
    )
}

/// Reads an item's prediction, or computes it with `predictor`; with the
/// file it came from (for messages: the reference view of a pair).
fn predict(
    item: &Item,
    predictor: Option<&dyn Predictor>,
) -> Result<(FloatImage, PathBuf), EvalError> {
    match (&item.prediction, predictor) {
        (Prediction::File(path), _) => Ok((read_disparity(path, None)?, path.clone())),
        (Prediction::Missing(folder), _) => Err(EvalError::MissingPrediction {
            name: item.name.clone(),
            folder: folder.clone(),
        }),
        (Prediction::Pair(pair), Some(predictor)) => {
            let disparity = predictor.predict(pair).map_err(EvalError::Predict)?;
            Ok((disparity, pair.reference.clone()))
        }
        (Prediction::Pair(pair), None) => Err(EvalError::NoSource(pair.reference.clone())),
    }
}

/// A source's predictions scored under one protocol's rules.
#[derive(Debug)]
pub struct SourceScores {
    /// The images scored; `None` when none could be.
    pub report: Option<ProtocolReport>,
    /// Each failed image's name and error, in the source's order.
    pub failed: Vec<(String, EvalError)>,
    /// The frames without usable ground truth, not scored.
    pub unscored: Vec<String>,
}

impl SourceScores {
    /// The scores as `eval --json` prints them: the report's JSON (see
    /// [`ProtocolReport::json`]) with the `unscored` frames; `None` when
    /// no image was scored.
    pub fn json(&self) -> Option<Value> {
        let mut json = self.report.as_ref()?.json();
        json["unscored"] = json!(self.unscored);
        Some(json)
    }
}

/// Scores the predictions in the folder `predictions` (`<name>.pfm`,
/// `.png` or `.exr` per pair) of `source`'s pairs with ground truth (only
/// those `frames` lists, each of which must be a frame of the source)
/// under `rules`, as `eval PREDICTIONS --FLAG DIR` does. A source off its
/// layout or an unreadable list is an error; an image that fails is in
/// [`SourceScores::failed`] and the others are scored.
pub fn score_predictions(
    source: &PairSource,
    predictions: &Path,
    frames: Option<&FrameList>,
    rules: &Rules,
    progress: &(dyn Fn(Progress<'_>) + Sync),
) -> Result<SourceScores, EvalError> {
    let mut listing = Listing::of(source)?;
    if let Some(list) = frames {
        check_listed(list, &[&listing], &source.place().display().to_string())?;
        listing = listing.keep(list);
    }
    let items = items(std::mem::take(&mut listing.pairs), Some(predictions));
    let scored = score_items(&items, None, None, rules, progress);
    Ok(SourceScores {
        report: (!scored.images.is_empty())
            .then(|| ProtocolReport::new(rules.clone(), scored.images)),
        failed: scored.failed,
        unscored: listing.unscored,
    })
}
