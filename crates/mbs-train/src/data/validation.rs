//! Held-out pairs with ground truth, scored during training under a named
//! protocol (`data.val_protocol`, the S3 paper's by default), through
//! `mbs-eval` as `eval` and `benchmark` score: EPE and Out-1, 2, 3 over
//! ALL, NOC and OCC pixels.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use mbs_core::formats::rgb::read_rgb;
use mbs_core::{FloatImage, MaskImage, RgbImage, Side};
use mbs_dataset::Manifest;
use mbs_dataset::StereoPair;
use mbs_dataset::ground_truth::{GroundTruth, GroundTruthFile};
use mbs_dataset::manifest::Split;
use mbs_dataset::pairs::{check_cameras, sample_pair, sample_view};
use mbs_eval::{Dataset, Metrics, Protocol, ProtocolReport, Region, Rules, rules_for, score_truth};

use crate::error::TrainError;
use mbs_nets::Backbone;
use mbs_nets::inference::predict_image;

/// One held-out pair with ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationPair {
    /// `<sample id> <reference>:<target>`.
    pub name: String,
    /// The views.
    pub pair: StereoPair,
    /// The reference view's ground truth.
    pub truth: GroundTruthFile,
    /// The farthest view on the target's side and its baseline ratio to
    /// the pair's: the student's target in the visual outputs, so the
    /// weight map shows what only the teacher sees.
    pub wide_target: (PathBuf, f64),
}

/// A pair's images and ground truth in memory.
#[derive(Debug, Clone)]
pub struct LoadedPair {
    /// The reference image.
    pub reference: RgbImage,
    /// The target image.
    pub target: RgbImage,
    /// Ground truth, `+inf` where unknown.
    pub gt: FloatImage,
    /// Non-occluded mask (non-zero = visible in the target), if known.
    pub noc: Option<MaskImage>,
}

impl ValidationPair {
    /// Reads the pair's files.
    pub fn load(&self) -> Result<LoadedPair, TrainError> {
        let gt = self.truth.load(None)?;
        Ok(LoadedPair {
            reference: read_rgb(&self.pair.reference)?,
            target: read_rgb(&self.pair.target)?,
            gt: gt.disparity,
            noc: gt.noc,
        })
    }

    /// Side of the target.
    pub fn side(&self) -> Side {
        self.pair.side
    }
}

/// The pairs validation scores, and the rules it scores them under.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationSet {
    /// In manifest order.
    pub pairs: Vec<ValidationPair>,
    /// The protocol's rules for a manifest's pairs (`Dataset::Other`).
    pub rules: Rules,
}

impl ValidationSet {
    /// Pairs `pairs` of the samples of `split` of a manifest read from
    /// `path` (`None`: the `val` split, or `test` when there is no `val`
    /// sample); at most `limit` samples (0 = all), scored under `protocol`.
    /// Samples without ground truth for a pair are skipped, so the set may
    /// be empty.
    pub fn from_manifest(
        path: &Path,
        manifest: &Manifest,
        pairs: &[[usize; 2]],
        (split, limit): (Option<Split>, usize),
        protocol: Protocol,
    ) -> Result<Self, TrainError> {
        let rules = rules_for(protocol, Dataset::Other, &[])
            .map_err(|e| TrainError::Config(format!("data.val_protocol: {e}")))?;
        let views = manifest.rig.num_views;
        let cameras: Vec<(usize, usize)> = pairs.iter().map(|&[r, t]| (r, t)).collect();
        check_cameras(path, manifest, &cameras)?;
        let held_out = |split| manifest.samples.iter().filter(move |s| s.split == split);
        let split = split.unwrap_or(if held_out(Split::Val).next().is_some() {
            Split::Val
        } else {
            Split::Test
        });
        let limit = if limit == 0 { usize::MAX } else { limit };
        let mut set = ValidationSet {
            pairs: Vec::new(),
            rules,
        };
        for sample in held_out(split).take(limit) {
            for &(reference, target) in &cameras {
                let mut pair = sample_pair(path, sample, (reference, target))?;
                let Some(truth) = pair.truth.take() else {
                    continue;
                };
                let wide = if target > reference { views - 1 } else { 0 };
                set.pairs.push(ValidationPair {
                    name: format!("{} {reference}:{target}", sample.id),
                    wide_target: (
                        sample_view(path, sample, wide)?,
                        manifest.rig.baseline_ratio(reference, wide, target),
                    ),
                    pair,
                    truth,
                });
            }
        }
        Ok(set)
    }

    /// Whether there is nothing to score.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Scores `net` on every pair under the set's rules (a pair whose
    /// ground truth has no valid pixel is left out).
    pub fn evaluate<B: Backbone>(
        &self,
        net: &B,
        device: &Device,
    ) -> Result<ValidationMetrics, TrainError> {
        let mut images = Vec::new();
        let (mut predicted, mut truth) = (Vec::new(), Vec::new());
        for pair in &self.pairs {
            let loaded = pair.load()?;
            if !loaded.gt.iter().any(|d| d.is_finite()) {
                continue;
            }
            let prediction =
                predict_image(net, &loaded.reference, &loaded.target, pair.side(), device)?;
            for (p, t) in prediction.as_raw().iter().zip(loaded.gt.as_raw().iter()) {
                if t.is_finite() && p.is_finite() {
                    predicted.push(*p);
                    truth.push(*t);
                }
            }
            let gt = GroundTruth {
                disparity: loaded.gt,
                noc: loaded.noc,
            };
            let at = &pair.truth.disparity;
            let score = score_truth(
                &gt,
                at,
                &prediction,
                &pair.pair.reference,
                None,
                &self.rules,
            )
            .map_err(|e| TrainError::data(at, e))?;
            images.push((pair.name.clone(), score));
        }
        Ok(ValidationMetrics {
            pairs: self.pairs.len(),
            report: ProtocolReport::new(self.rules.clone(), images),
            range: DisparityRange::of(predicted, truth),
        })
    }
}

/// Share of the pixels below the percentile that measures a range.
pub const RANGE_PERCENTILE: f64 = 0.95;

/// How far the disparities reach over the scored pixels (those with
/// ground truth): the [`RANGE_PERCENTILE`] of the prediction and of the
/// ground truth, in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DisparityRange {
    /// The prediction's percentile.
    pub predicted: f32,
    /// The ground truth's percentile.
    pub truth: f32,
}

impl DisparityRange {
    /// The percentiles of `predicted` and `truth` (the same pixels);
    /// `None` when there is no pixel.
    pub fn of(predicted: Vec<f32>, truth: Vec<f32>) -> Option<Self> {
        Some(Self {
            predicted: percentile(predicted, RANGE_PERCENTILE)?,
            truth: percentile(truth, RANGE_PERCENTILE)?,
        })
    }
}

/// The value below which the share `p` of `values` lies (nearest rank).
fn percentile(mut values: Vec<f32>, p: f64) -> Option<f32> {
    let last = values.len().checked_sub(1)?;
    let rank = ((last as f64) * p).round() as usize;
    Some(*values.select_nth_unstable_by(rank, f32::total_cmp).1)
}

/// Validation figures under the set's protocol.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationMetrics {
    /// Pairs scored.
    pub pairs: usize,
    /// Each pair's scores and the set's, under the protocol's rules.
    pub report: ProtocolReport,
    /// How far the prediction and the ground truth reach (`None` without
    /// a scored pixel).
    pub range: Option<DisparityRange>,
}

impl ValidationMetrics {
    /// The protocol's figures in `region`, if any pair has pixels there
    /// (NOC and OCC need masks).
    pub fn region(&self, region: Region) -> Option<Metrics> {
        self.report.summary(region).map(|summary| summary.metrics)
    }

    /// The protocol's figures over every scored pixel (`None`: none).
    pub fn all(&self) -> Option<Metrics> {
        self.region(Region::All)
    }
}
