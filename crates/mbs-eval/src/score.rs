//! One image scored under a protocol's [`Rules`] ([`Rules::score`]): the
//! counts of each region, and a set of images combined as the protocol
//! combines them ([`Rules::summarise`]).

use mbs_core::{FloatImage, MaskImage};

use crate::prediction::prepare;
use crate::protocol::{Aggregation, PredictionRule, ProtocolError, Regions, Rules};
use crate::sums::{D1_ABS_PX, ErrorSums, MeanMetrics, Metrics, MetricsError, Region, RegionSums};

/// The KITTI devkits' relative D1 bound, compared in double precision as
/// `#define REL_THRESH 0.05` is.
const KITTI_REL_THRESH: f64 = 0.05;

/// One image to score.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    /// The predicted disparity (evaldisp also takes 1/2 or 1/4 of the
    /// ground truth's size).
    pub prediction: &'a FloatImage,
    /// The ground truth, `+inf` where unknown.
    pub gt: &'a FloatImage,
    /// The non-occluded mask (non-zero = non-occluded), if known.
    pub noc: Option<&'a MaskImage>,
    /// The scene's disparity bound at the ground truth's resolution
    /// (Middlebury's `ndisp`), if stated.
    pub disparity_bound: Option<u32>,
}

/// Counts of one region of one image, or of a pooled set.
#[derive(Debug, Clone, PartialEq)]
pub struct Tally {
    /// Ground-truth pixels the protocol scores in the region.
    pub ground_truth: u64,
    /// Of those, pixels where the prediction had a value.
    pub estimated: u64,
    /// Error sums over the pixels the figures are over (ETH3D: the
    /// estimated ones; else all of them).
    pub sums: ErrorSums,
}

impl Tally {
    /// An empty tally at `thresholds`.
    fn new(thresholds: &[f32]) -> Tally {
        Tally {
            ground_truth: 0,
            estimated: 0,
            sums: ErrorSums::with_thresholds(thresholds),
        }
    }

    /// Adds a pixel: the prepared value `d` against `gt`, whether the
    /// prediction had a value there, as `rule` counts it.
    fn add(&mut self, rule: PredictionRule, d: f32, gt: f32, estimated: bool) {
        self.ground_truth += 1;
        self.estimated += u64::from(estimated);
        match rule {
            PredictionRule::Eth3dEstimated if !estimated => {}
            // evaluate_scene_flow.cpp: fabs(d_gt-d_est)>ABS_THRESH &&
            // fabs(d_gt-d_est)/fabs(d_gt)>REL_THRESH, in float.
            PredictionRule::KittiBackground => self.sums.add_judged(d, gt, |err| {
                err > D1_ABS_PX && f64::from(err / gt.abs()) > KITTI_REL_THRESH
            }),
            _ => self.sums.add(d, gt),
        }
    }

    /// Pools `other` into this tally.
    fn merge(&mut self, other: &Tally) {
        self.ground_truth += other.ground_truth;
        self.estimated += other.estimated;
        self.sums.merge(&other.sums);
    }
}

/// One image's tallies, per region the protocol reports, in
/// [`Region::EVERY`] order.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageScore {
    /// The regions and their tallies.
    pub regions: Vec<(Region, Tally)>,
}

impl ImageScore {
    /// The tally of `region`, if reported.
    pub fn get(&self, region: Region) -> Option<&Tally> {
        self.regions
            .iter()
            .find(|(r, _)| *r == region)
            .map(|(_, t)| t)
    }

    /// The error sums per region, as [`crate::evaluate`] gives them (the
    /// `pixels` protocol's report).
    pub fn region_sums(&self) -> RegionSums {
        let sums = |region| self.get(region).map(|t| t.sums.clone());
        RegionSums {
            all: sums(Region::All).unwrap_or_default(),
            noc: sums(Region::Noc),
            occ: sums(Region::Occ),
        }
    }
}

/// A set's figures in one region, combined as the protocol combines them.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Images with ground truth in the region.
    pub images: u64,
    /// The figures; `pixels` is the number of ground-truth pixels of
    /// those images.
    pub metrics: Metrics,
}

impl Rules {
    /// Scores one image: each region's counts under these rules. An error
    /// when the sizes do not fit or NOC is needed and there is no mask.
    pub fn score(&self, frame: &Frame<'_>) -> Result<ImageScore, ProtocolError> {
        let size = frame.gt.dimensions();
        if let Some(mask) = frame.noc.filter(|m| m.dimensions() != size) {
            return Err(MetricsError::SizeMismatch {
                what: "the non-occluded mask",
                expected: size,
                actual: mask.dimensions(),
            }
            .into());
        }
        let prepared = prepare(
            self.prediction,
            frame.prediction,
            size,
            frame.disparity_bound,
        )?;
        let mut regions = self.empty_regions(frame.noc.is_some())?;
        for (i, &gt) in frame.gt.as_raw().iter().enumerate() {
            if !self.valid.contains(gt) {
                continue;
            }
            let noc = frame.noc.map(|m| m.as_raw()[i] != 0);
            for (region, tally) in &mut regions {
                let inside = match region {
                    Region::All => true,
                    Region::Noc => noc == Some(true),
                    Region::Occ => noc == Some(false),
                };
                if inside {
                    let (d, estimated) = (prepared.values[i], prepared.estimated[i]);
                    tally.add(self.prediction, d, gt, estimated);
                }
            }
        }
        Ok(ImageScore { regions })
    }

    /// Empty tallies of the regions these rules report for an image with
    /// (`masked`) or without an occlusion mask.
    fn empty_regions(&self, masked: bool) -> Result<Vec<(Region, Tally)>, ProtocolError> {
        let regions: &[Region] = match (self.regions, masked) {
            (Regions::Masked, true) => &Region::EVERY,
            (Regions::Masked, false) | (Regions::AllOnly, _) => &[Region::All],
            (Regions::NocOnly, true) => &[Region::Noc],
            (Regions::NocOnly, false) => {
                return Err(ProtocolError::NeedsMask {
                    protocol: self.protocol,
                    dataset: self.dataset,
                });
            }
        };
        Ok(regions
            .iter()
            .map(|&r| (r, Tally::new(&self.thresholds)))
            .collect())
    }

    /// The figures of one tally (an image's region, or a pooled set):
    /// `pixels` are the ground-truth pixels, the density the share that
    /// had a value; figures the protocol does not define are `None`.
    pub fn metrics(&self, tally: &Tally) -> Metrics {
        let mut m = tally.sums.metrics();
        m.pixels = tally.ground_truth;
        m.density = (tally.ground_truth > 0)
            .then(|| 100.0 * tally.estimated as f64 / tally.ground_truth as f64);
        let nothing_estimated = tally.sums.pixels == 0 && tally.ground_truth > 0;
        if self.prediction == PredictionRule::Eth3dEstimated && nothing_estimated {
            // main.cc: with no estimated pixel every bad-x is 1.
            m.out.iter_mut().for_each(|(_, v)| *v = Some(100.0));
        }
        if !self.d1 {
            m.d1 = None;
        }
        if self.epe.is_none() {
            m.epe = None;
        }
        m
    }

    /// Combines `tallies` (one region of each image) as the protocol does;
    /// images without ground truth in the region are left out, and `None`
    /// is returned when none is left.
    pub fn summarise<'a>(&self, tallies: impl IntoIterator<Item = &'a Tally>) -> Option<Summary> {
        let mut pooled = Tally::new(&self.thresholds);
        let mut mean = MeanMetrics::new();
        let mut images = 0;
        for tally in tallies.into_iter().filter(|t| t.ground_truth > 0) {
            pooled.merge(tally);
            mean.add(&self.metrics(tally));
            images += 1;
        }
        if images == 0 {
            return None;
        }
        let pooled = self.metrics(&pooled);
        let mean = mean.mean();
        let pick = |a: Aggregation| match a {
            Aggregation::Pooled => &pooled,
            Aggregation::PerImage => &mean,
        };
        let outliers = pick(self.outliers);
        Some(Summary {
            images,
            metrics: Metrics {
                pixels: pooled.pixels,
                epe: self.epe.and_then(|a| pick(a).epe),
                out: outliers.out.clone(),
                d1: outliers.d1,
                density: outliers.density,
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use mbs_dataset::benchmark::Dataset;

    use super::*;
    use crate::protocol::Protocol;

    fn map(values: &[f32]) -> FloatImage {
        FloatImage::from_raw(values.len() as u32, 1, values.to_vec()).unwrap()
    }

    fn score(
        protocol: Protocol,
        dataset: Dataset,
        pred: &[f32],
        gt: &[f32],
        noc: &[u8],
    ) -> ImageScore {
        let mask = MaskImage::from_raw(noc.len() as u32, 1, noc.to_vec()).unwrap();
        let frame = Frame {
            prediction: &map(pred),
            gt: &map(gt),
            noc: (!noc.is_empty()).then_some(&mask),
            disparity_bound: None,
        };
        protocol.rules(dataset).unwrap().score(&frame).unwrap()
    }

    #[test]
    fn s3_caps_the_ground_truth_and_splits_noc_and_occ() {
        // 200 is above the cap, 0 below it: two pixels left, one per region.
        let image = score(
            Protocol::S3,
            Dataset::Kitti2015,
            &[10.0, 25.0, 1.0, 1.0],
            &[11.0, 20.0, 200.0, 0.0],
            &[255, 0, 255, 255],
        );
        let ground_truth = |r| image.get(r).unwrap().ground_truth;
        assert_eq!(
            (
                ground_truth(Region::All),
                ground_truth(Region::Noc),
                ground_truth(Region::Occ)
            ),
            (2, 1, 1)
        );
        let rules = Protocol::S3.rules(Dataset::Kitti2015).unwrap();
        let occ = rules.metrics(image.get(Region::Occ).unwrap());
        assert_eq!((occ.out(3.0), occ.epe), (Some(100.0), Some(5.0)));
    }

    #[test]
    fn per_image_means_skip_images_without_the_region() {
        let rules = Protocol::S3.rules(Dataset::Middlebury).unwrap();
        let a = score(
            Protocol::S3,
            Dataset::Middlebury,
            &[1.0, 9.0],
            &[1.0, 1.0],
            &[255, 0],
        );
        let b = score(Protocol::S3, Dataset::Middlebury, &[5.0], &[1.0], &[255]);
        let images = [&a, &b];
        let summary = |r| {
            rules
                .summarise(images.iter().filter_map(|i| i.get(r)))
                .unwrap()
        };
        // OCC: only image a has it (one outlier of one); NOC: 0 % and 100 %.
        assert_eq!(summary(Region::Occ).images, 1);
        assert_eq!(summary(Region::Occ).metrics.out(2.0), Some(100.0));
        assert_eq!(summary(Region::Noc).metrics.out(2.0), Some(50.0));
        // ALL: a is 50 %, b 100 %: mean 75 % (pooled would be 2/3).
        assert_eq!(summary(Region::All).metrics.out(2.0), Some(75.0));
        assert_eq!(summary(Region::All).metrics.pixels, 3);
    }

    #[test]
    fn igev_needs_the_mask_where_it_scores_noc_only() {
        let rules = Protocol::IgevStereo.rules(Dataset::Eth3d).unwrap();
        let frame = Frame {
            prediction: &map(&[1.0]),
            gt: &map(&[1.0]),
            noc: None,
            disparity_bound: None,
        };
        let err = rules.score(&frame).unwrap_err().to_string();
        assert!(err.contains("non-occluded pixels of ETH3D"), "{err}");
    }

    #[test]
    fn eth3d_scores_estimated_pixels_and_reports_coverage() {
        let rules = Protocol::Eth3d.rules(Dataset::Eth3d).unwrap();
        let image = score(
            Protocol::Eth3d,
            Dataset::Eth3d,
            &[1.0, 3.5, f32::NAN, 9.0],
            &[1.0; 4],
            &[],
        );
        let m = rules.metrics(image.get(Region::All).unwrap());
        // 9 is beyond the width, NaN not finite: 2 of 4 estimated; bad-1
        // over those 2: 3.5 is off by 2.5.
        assert_eq!((m.pixels, m.density), (4, Some(50.0)));
        assert_eq!((m.out(1.0), m.epe), (Some(50.0), Some(1.25)));
        let none = score(Protocol::Eth3d, Dataset::Eth3d, &[f32::NAN], &[1.0], &[]);
        let m = rules.metrics(none.get(Region::All).unwrap());
        assert_eq!(
            (m.out(1.0), m.epe, m.density),
            (Some(100.0), None, Some(0.0))
        );
    }

    #[test]
    fn kitti_2015_fills_holes_and_pools_d1_without_epe() {
        let rules = Protocol::Kitti.rules(Dataset::Kitti2015).unwrap();
        // The hole takes the smaller neighbour, 10: off by 30 from 40.
        let image = score(
            Protocol::Kitti,
            Dataset::Kitti2015,
            &[10.0, f32::NAN, 50.0],
            &[10.0, 40.0, 50.0],
            &[],
        );
        let m = rules.metrics(image.get(Region::All).unwrap());
        assert!((m.d1.unwrap() - 100.0 / 3.0).abs() < 1e-9);
        assert!((m.density.unwrap() - 200.0 / 3.0).abs() < 1e-9);
        assert_eq!(m.epe, None);
    }
}
