//! The images `eval` and `benchmark` score: the pairs of a source with
//! ground truth (only the listed frames with `--frames`), the frames left
//! out for want of usable ground truth, each pair's prediction read or
//! computed, and every image scored under a protocol's rules
//! ([`mbs_core::metrics::Rules::score`]) with a progress bar.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use anyhow::bail;
use mbs_core::FloatImage;
use mbs_core::formats::{read_disparity, rgb};
use mbs_core::metrics::{Dataset, Frame, ImageScore, ProtocolError, Rules};
use mbs_dataset::StereoPair;
use mbs_dataset::benchmark::Benchmark;
use mbs_dataset::ground_truth::{GroundTruthFile, find_map};
use mbs_dataset::pairs::PairSource;

use crate::cli::batch;
use crate::cli::pairs::FrameList;
use crate::cli::source::PairMatcher;

/// One image to score.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    /// Name in the table.
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
    /// is reported as failed and the others are scored.
    Missing(PathBuf),
    /// A pair the disparity source predicts.
    Pair(StereoPair),
}

/// A source's pairs with ground truth, and its frames without.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Listing {
    /// The pairs with ground truth, in dataset order.
    pub pairs: Vec<StereoPair>,
    /// The frames whose ground truth is missing or is not a regular file
    /// (a folder, a FIFO), which are not scored.
    pub unscored: Vec<String>,
    /// Every frame name of the source, scored or not.
    pub frames: HashSet<String>,
}

impl Listing {
    /// The pairs of `source` with ground truth, and the names of its
    /// frames without (its views' frames that are not among them; none
    /// when the views cannot be listed, e.g. a KITTI folder of ground
    /// truth alone).
    pub fn of(source: &PairSource) -> anyhow::Result<Listing> {
        let pairs = source.scored_pairs()?;
        let scored: HashSet<&str> = pairs.iter().map(|p| p.id.as_str()).collect();
        let every = source.pairs().unwrap_or_default();
        let unscored: Vec<String> = every
            .iter()
            .filter(|p| !scored.contains(p.id.as_str()))
            .map(|p| p.id.clone())
            .collect();
        let frames = every
            .into_iter()
            .map(|p| p.id)
            .chain(scored.iter().map(|s| s.to_string()));
        Ok(Listing {
            frames: frames.collect(),
            pairs,
            unscored,
        })
    }

    /// Only the frames `list` names.
    pub fn keep(self, list: &FrameList) -> Listing {
        Listing {
            pairs: self
                .pairs
                .into_iter()
                .filter(|p| list.contains(&p.id))
                .collect(),
            unscored: self
                .unscored
                .into_iter()
                .filter(|name| list.contains(name))
                .collect(),
            frames: self.frames,
        }
    }

    /// Prints a warning line naming the unscored frames of `label`, if any.
    pub fn warn_unscored(&self, label: &str) {
        if let Some(line) = unscored_line(label, &self.unscored) {
            eprintln!("{line}");
        }
    }
}

/// The warning line for `unscored` frames of `label` (the first 20 named).
fn unscored_line(label: &str, unscored: &[String]) -> Option<String> {
    const NAMED: usize = 20;
    if unscored.is_empty() {
        return None;
    }
    let mut names = unscored[..unscored.len().min(NAMED)].join(", ");
    if unscored.len() > NAMED {
        names += &format!(" and {} more", unscored.len() - NAMED);
    }
    Some(format!(
        "warning: {label}: {} frame(s) not scored, without usable ground truth (missing, or \
         not a regular file): {names}",
        unscored.len()
    ))
}

/// The dataset whose rules score `source`'s pairs: the benchmark (KITTI
/// with its year), or other data for manifests and single pairs.
pub fn dataset_of(source: &PairSource) -> Dataset {
    match source {
        PairSource::Kitti { dir, .. } => (Benchmark::Kitti.layout().dataset)(dir),
        PairSource::Benchmark { benchmark, dir } => (benchmark.layout().dataset)(dir),
        PairSource::Single { .. } | PairSource::Manifest { .. } => Dataset::Other,
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

/// Scores every item under `rules` with a progress bar: its prediction
/// (read, or computed by `matcher`) against its ground truth (integer
/// files read at `gt_scale` codes per pixel). An item that fails is
/// reported on stderr and counted in the summary; the others are scored.
pub fn score_all(
    items: &[Item],
    matcher: Option<&PairMatcher>,
    gt_scale: Option<f32>,
    rules: &Rules,
) -> (Vec<(String, ImageScore)>, batch::Summary) {
    let (results, summary) = batch::map(
        items,
        "images",
        |item| item.name.clone(),
        |item| {
            let prediction = predict(item, matcher)?;
            score(item, &prediction, gt_scale, rules)
        },
    );
    let scored = items
        .iter()
        .zip(results)
        .filter_map(|(item, score)| Some((item.name.clone(), score?)))
        .collect();
    (scored, summary)
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

/// Scores one item's `prediction` (read from `source`) under `rules`.
fn score(
    item: &Item,
    (prediction, source): &(FloatImage, PathBuf),
    gt_scale: Option<f32>,
    rules: &Rules,
) -> anyhow::Result<ImageScore> {
    let gt_path = &item.truth.disparity;
    let gt = item.truth.load(gt_scale)?;
    if !gt.disparity.iter().any(|d| d.is_finite()) {
        bail!(
            "{}: the ground truth has no valid pixel: nothing to score",
            gt_path.display()
        );
    }
    let frame = Frame {
        prediction,
        gt: &gt.disparity,
        noc: gt.noc.as_ref(),
        disparity_bound: item.disparity_bound,
    };
    rules.score(&frame).map_err(|e| match e {
        ProtocolError::NeedsMask { .. } => anyhow::anyhow!("{}: {e}", gt_path.display()),
        _ => anyhow::anyhow!(
            "{}: {e} (ground truth {})",
            source.display(),
            gt_path.display()
        ),
    })
}

/// The frame list's names that none of `listings` has: an error naming
/// them and the list, with `places` saying where they were looked for.
pub fn check_listed(list: &FrameList, listings: &[&Listing], places: &str) -> anyhow::Result<()> {
    let missing: Vec<&str> = list
        .names
        .iter()
        .map(String::as_str)
        .filter(|name| !listings.iter().any(|l| l.frames.contains(*name)))
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    bail!(
        "{}: {} listed frame(s) not found in {places}: {}",
        list.path.display(),
        missing.len(),
        missing.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_unscored_line_names_the_first_twenty_frames() {
        assert_eq!(unscored_line("KITTI 2015 training", &[]), None);
        let two = ["a".to_string(), "b".to_string()];
        assert_eq!(
            unscored_line("ETH3D x", &two).unwrap(),
            "warning: ETH3D x: 2 frame(s) not scored, without usable ground truth (missing, or \
             not a regular file): a, b"
        );
        let many: Vec<String> = (0..23).map(|i| format!("f{i}")).collect();
        let line = unscored_line("x", &many).unwrap();
        assert!(line.ends_with("f18, f19 and 3 more"), "{line}");
    }
}
