//! Held-out pairs with ground truth, scored during training: EPE and Out-x
//! over ALL, NOC and OCC pixels, pooled over the set (SPEC §6).

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use mbs_core::formats::read_disparity;
use mbs_core::formats::rgb::{read_mask, read_rgb};
use mbs_core::metrics::{Metrics, Region, RegionSums, evaluate};
use mbs_core::{FloatImage, MaskImage, RgbImage, Side};
use mbs_dataset::Manifest;
use mbs_dataset::manifest::{Split, resolve};

use crate::backbone::Backbone;
use crate::error::TrainError;
use crate::inference::predict_image;

/// Out-x thresholds tracked by validation.
pub const THRESHOLDS: [f32; 3] = [1.0, 2.0, 3.0];

/// One held-out pair with ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationPair {
    /// `<sample id> <reference>:<target>`.
    pub name: String,
    /// The reference image.
    pub reference: PathBuf,
    /// The target image.
    pub target: PathBuf,
    /// Side of the target.
    pub side: Side,
    /// Ground-truth disparity file.
    pub gt: PathBuf,
    /// The pair's disparity is this times the file's values.
    pub gt_scale: f32,
    /// Mask of occluded reference pixels (255 = occluded), if any.
    pub occlusion: Option<PathBuf>,
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
        let image = |p: &Path| read_rgb(p);
        let mut gt = read_disparity(&self.gt, None)?;
        if self.gt_scale != 1.0 {
            gt.iter_mut().for_each(|d| *d *= self.gt_scale);
        }
        let noc = match &self.occlusion {
            Some(path) => {
                let mut mask = read_mask(path)?;
                mask.iter_mut()
                    .for_each(|v| *v = if *v == 0 { 255 } else { 0 });
                Some(mask)
            }
            None => None,
        };
        Ok(LoadedPair {
            reference: image(&self.reference)?,
            target: image(&self.target)?,
            gt,
            noc,
        })
    }
}

/// The pairs validation scores.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ValidationSet {
    /// In manifest order.
    pub pairs: Vec<ValidationPair>,
}

impl ValidationSet {
    /// Pairs `pairs` of the samples of `split` of a manifest read from
    /// `path` (`None`: the `val` split, or `test` when there is no `val`
    /// sample); at most `limit` samples (0 = all). Samples without ground
    /// truth for a pair are skipped, so the set may be empty.
    pub fn from_manifest(
        path: &Path,
        manifest: &Manifest,
        pairs: &[[usize; 2]],
        split: Option<Split>,
        limit: usize,
    ) -> Result<Self, TrainError> {
        let views = manifest.rig.num_views;
        for &[reference, target] in pairs {
            if reference >= views || target >= views || reference == target {
                return Err(TrainError::data(
                    path,
                    format!(
                        "validation pair {reference}:{target} does not fit a {views}-camera rig"
                    ),
                ));
            }
        }
        let held_out = |split| manifest.samples.iter().filter(move |s| s.split == split);
        let split = split.unwrap_or(if held_out(Split::Val).next().is_some() {
            Split::Val
        } else {
            Split::Test
        });
        let limit = if limit == 0 { usize::MAX } else { limit };
        let mut set = ValidationSet::default();
        for sample in held_out(split).take(limit) {
            for &[reference, target] in pairs {
                let Some(gt) = sample
                    .ground_truth
                    .iter()
                    .find(|g| g.reference == reference && g.target == target)
                else {
                    continue;
                };
                let view = |k: usize| {
                    sample
                        .views
                        .get(k)
                        .map(|v| resolve(path, v))
                        .ok_or_else(|| {
                            TrainError::data(path, format!("sample {} has no view {k}", sample.id))
                        })
                };
                let wide = if target > reference { views - 1 } else { 0 };
                set.pairs.push(ValidationPair {
                    name: format!("{} {reference}:{target}", sample.id),
                    reference: view(reference)?,
                    target: view(target)?,
                    side: if target > reference {
                        Side::Right
                    } else {
                        Side::Left
                    },
                    gt: resolve(path, &gt.disparity),
                    gt_scale: gt.scale as f32,
                    occlusion: gt.occlusion.as_ref().map(|o| resolve(path, o)),
                    wide_target: (
                        view(wide)?,
                        manifest.rig.baseline_ratio(reference, wide, target),
                    ),
                });
            }
        }
        Ok(set)
    }

    /// Whether there is nothing to score.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Scores `net` on every pair, pooled over pixels.
    pub fn evaluate<B: Backbone>(
        &self,
        net: &B,
        device: &Device,
    ) -> Result<ValidationMetrics, TrainError> {
        let mut pooled = RegionSums::default();
        for pair in &self.pairs {
            let loaded = pair.load()?;
            let prediction =
                predict_image(net, &loaded.reference, &loaded.target, pair.side, device)?;
            let sums = evaluate(&prediction, &loaded.gt, loaded.noc.as_ref(), &THRESHOLDS)
                .map_err(|e| TrainError::data(&pair.gt, e))?;
            pooled.merge(&sums);
        }
        Ok(ValidationMetrics {
            pairs: self.pairs.len(),
            all: pooled.all.metrics(),
            noc: pooled.noc.as_ref().map(|s| s.metrics()),
            occ: pooled.occ.as_ref().map(|s| s.metrics()),
        })
    }
}

/// Validation metrics pooled over pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationMetrics {
    /// Pairs scored.
    pub pairs: usize,
    /// Over every valid GT pixel.
    pub all: Metrics,
    /// Over non-occluded pixels, when masks exist.
    pub noc: Option<Metrics>,
    /// Over occluded pixels, when masks exist.
    pub occ: Option<Metrics>,
}

impl ValidationMetrics {
    /// The metrics of `region`, if tracked.
    pub fn region(&self, region: Region) -> Option<&Metrics> {
        match region {
            Region::All => Some(&self.all),
            Region::Noc => self.noc.as_ref(),
            Region::Occ => self.occ.as_ref(),
        }
    }
}
