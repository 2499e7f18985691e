//! Disparity error metrics (conventions §6): EPE, Out-x and KITTI D1 over ALL valid
//! ground-truth pixels, over the non-occluded ones (NOC) and over the
//! occluded ones (OCC = ALL minus NOC).
//!
//! Everything is computed from [`ErrorSums`], pixel counts and error sums that
//! add up: the metrics of one image come from its sums, the pixel-pooled
//! metrics of a set from the merged sums ([`ErrorSums::merge`]), and the
//! per-image averages from [`MeanMetrics`], which averages per-image
//! [`Metrics`]. So all three share one code path.
//!
//! Conventions:
//! - A ground-truth pixel is valid when it is finite (readers turn the `0`
//!   of integer files into `+inf`). Invalid GT pixels are never counted.
//! - A **missing prediction** (non-finite value at a valid GT pixel) counts
//!   as an error of unbounded size: it is an outlier for every Out-x and for
//!   D1, and it is left out of EPE, which is the mean over the pixels that
//!   have a prediction. [`Metrics::density`] says which share of pixels had
//!   one. A matcher that wants KITTI-style scoring fills its holes before
//!   evaluation (the built-in SGM does, from the background side).
//! - An empty set of pixels gives `None`, never `NaN`.
//!
//! Those are the `pixels` protocol's rules; [`crate::Protocol`] names the
//! other projects' rules (stereo_toolbox, RAFT-Stereo, IGEV-Stereo, the
//! KITTI, ETH3D and Middlebury evaluators), scored through
//! [`crate::Rules::score`] and combined by [`crate::ProtocolReport`].

#[cfg(test)]
use mbs_core::{FloatImage, MaskImage};

/// The Out-x thresholds tracked by [`ErrorSums::new`] (pixels).
pub const DEFAULT_OUT_THRESHOLDS: [f32; 3] = [1.0, 2.0, 3.0];

/// KITTI D1: an outlier has an error above this many pixels…
pub const D1_ABS_PX: f32 = 3.0;
/// …and above this fraction of the ground-truth disparity.
pub const D1_REL: f32 = 0.05;

/// Why two maps cannot be compared.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MetricsError {
    /// The prediction, the ground truth or the mask differ in size.
    #[error("{what} is {actual:?} (width, height) but the ground truth is {expected:?}")]
    SizeMismatch {
        /// Which input has the wrong size.
        what: &'static str,
        /// Size of the ground truth.
        expected: (u32, u32),
        /// Size of the offending input.
        actual: (u32, u32),
    },
}

/// Counts and sums over a set of pixels, from which every metric follows.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorSums {
    thresholds: Vec<f32>,
    /// Valid ground-truth pixels counted.
    pub pixels: u64,
    /// Of those, pixels without a (finite) prediction.
    pub missing: u64,
    /// Sum of `|d - gt|` over the pixels with a prediction.
    pub abs_error_sum: f64,
    /// Per threshold (same order as [`ErrorSums::thresholds`]), pixels with
    /// an error above it, missing predictions included.
    pub outliers: Vec<u64>,
    /// KITTI D1 outliers (error > 3 px and > 5 % of GT), missing included.
    pub d1_outliers: u64,
}

impl Default for ErrorSums {
    fn default() -> Self {
        Self::new()
    }
}

impl ErrorSums {
    /// Empty sums tracking Out-1, Out-2 and Out-3.
    pub fn new() -> Self {
        Self::with_thresholds(&DEFAULT_OUT_THRESHOLDS)
    }

    /// Empty sums tracking Out-x for each `x` in `thresholds` (pixels).
    pub fn with_thresholds(thresholds: &[f32]) -> Self {
        Self {
            thresholds: thresholds.to_vec(),
            pixels: 0,
            missing: 0,
            abs_error_sum: 0.0,
            outliers: vec![0; thresholds.len()],
            d1_outliers: 0,
        }
    }

    /// The Out-x thresholds tracked, in pixels.
    pub fn thresholds(&self) -> &[f32] {
        &self.thresholds
    }

    /// Adds one pixel: `prediction` against a `gt` that the caller has
    /// checked to be valid (finite).
    pub fn add(&mut self, prediction: f32, gt: f32) {
        self.add_judged(prediction, gt, |err| {
            err > D1_ABS_PX && err > D1_REL * gt.abs()
        });
    }

    /// Adds one pixel as [`ErrorSums::add`] does, with `d1` judging whether
    /// a finite error is a D1 outlier (for a devkit's own arithmetic).
    pub fn add_judged(&mut self, prediction: f32, gt: f32, d1: impl Fn(f32) -> bool) {
        self.pixels += 1;
        if !prediction.is_finite() {
            self.missing += 1;
            self.d1_outliers += 1;
            self.outliers.iter_mut().for_each(|n| *n += 1);
            return;
        }
        let err = (prediction - gt).abs();
        self.abs_error_sum += f64::from(err);
        for (n, &x) in self.outliers.iter_mut().zip(&self.thresholds) {
            *n += u64::from(err > x);
        }
        self.d1_outliers += u64::from(d1(err));
    }

    /// Adds the sums of `other` (pixel pooling). Both must track the same
    /// thresholds; counts of thresholds `other` lacks are left as they are.
    /// Sums with no pixel yet take `other` as it is (thresholds included),
    /// so `ErrorSums::default()` can start any pool.
    pub fn merge(&mut self, other: &ErrorSums) {
        if self.pixels == 0 {
            *self = other.clone();
            return;
        }
        self.pixels += other.pixels;
        self.missing += other.missing;
        self.abs_error_sum += other.abs_error_sum;
        self.d1_outliers += other.d1_outliers;
        for (i, &x) in self.thresholds.iter().enumerate() {
            if let Some(j) = other.thresholds.iter().position(|&y| y == x) {
                self.outliers[i] += other.outliers[j];
            }
        }
    }

    /// The metrics these sums give.
    pub fn metrics(&self) -> Metrics {
        let pct = |n: u64| (self.pixels > 0).then(|| 100.0 * n as f64 / self.pixels as f64);
        let predicted = self.pixels - self.missing;
        Metrics {
            pixels: self.pixels,
            epe: (predicted > 0).then(|| self.abs_error_sum / predicted as f64),
            out: self
                .thresholds
                .iter()
                .zip(&self.outliers)
                .map(|(&x, &n)| (x, pct(n)))
                .collect(),
            d1: pct(self.d1_outliers),
            density: pct(predicted),
        }
    }
}

/// Metrics of one set of pixels. Percentages are in `[0, 100]`; `None` means
/// no pixel was counted.
#[derive(Debug, Clone, PartialEq)]
pub struct Metrics {
    /// Valid ground-truth pixels counted.
    pub pixels: u64,
    /// End-point error: mean `|d - gt|` (pixels) over pixels with a prediction.
    pub epe: Option<f64>,
    /// `(x, Out-x)`: percentage of pixels with error above `x` pixels.
    pub out: Vec<(f32, Option<f64>)>,
    /// KITTI D1: percentage of pixels with error > 3 px and > 5 % of GT.
    pub d1: Option<f64>,
    /// Percentage of pixels that had a prediction.
    pub density: Option<f64>,
}

impl Metrics {
    /// Out-x for a tracked threshold `x`; `None` when `x` is not tracked or
    /// no pixel was counted.
    pub fn out(&self, x: f32) -> Option<f64> {
        self.out.iter().find(|(t, _)| *t == x).and_then(|(_, v)| *v)
    }
}

/// Which pixels of an image a set of sums covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Region {
    /// Every pixel with valid ground truth.
    All,
    /// Valid pixels inside the non-occluded mask.
    Noc,
    /// Valid pixels outside the non-occluded mask.
    Occ,
}

impl Region {
    /// The three regions, in table order.
    pub const EVERY: [Region; 3] = [Region::All, Region::Noc, Region::Occ];

    /// Upper-case name used in tables and JSON (`ALL`, `NOC`, `OCC`).
    pub fn name(self) -> &'static str {
        match self {
            Region::All => "ALL",
            Region::Noc => "NOC",
            Region::Occ => "OCC",
        }
    }
}

/// Sums of one image (or a pooled set) per region. NOC and OCC are `None`
/// when no non-occluded mask was given.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RegionSums {
    /// All valid ground-truth pixels.
    pub all: ErrorSums,
    /// Non-occluded pixels, when a mask was given.
    pub noc: Option<ErrorSums>,
    /// Occluded pixels (ALL minus NOC), when a mask was given.
    pub occ: Option<ErrorSums>,
}

impl RegionSums {
    /// The sums of `region`, if tracked.
    pub fn get(&self, region: Region) -> Option<&ErrorSums> {
        match region {
            Region::All => Some(&self.all),
            Region::Noc => self.noc.as_ref(),
            Region::Occ => self.occ.as_ref(),
        }
    }

    /// Pools `other` into `self` (a region missing on either side is kept
    /// from the side that has it).
    pub fn merge(&mut self, other: &RegionSums) {
        self.all.merge(&other.all);
        for (mine, theirs) in [(&mut self.noc, &other.noc), (&mut self.occ, &other.occ)] {
            match (mine.as_mut(), theirs) {
                (Some(m), Some(t)) => m.merge(t),
                (None, Some(t)) => *mine = Some(t.clone()),
                _ => {}
            }
        }
    }
}

/// Compares a predicted disparity with ground truth over ALL valid GT
/// pixels and, when `noc` is given (non-zero = non-occluded), over NOC and
/// OCC. Tracks Out-x for each of `thresholds`. The tests' way to the sums'
/// arithmetic; the protocols score through [`crate::Rules::score`].
#[cfg(test)]
pub(crate) fn evaluate(
    prediction: &FloatImage,
    gt: &FloatImage,
    noc: Option<&MaskImage>,
    thresholds: &[f32],
) -> Result<RegionSums, MetricsError> {
    let expected = gt.dimensions();
    if prediction.dimensions() != expected {
        return Err(MetricsError::SizeMismatch {
            what: "the prediction",
            expected,
            actual: prediction.dimensions(),
        });
    }
    if let Some(mask) = noc.filter(|m| m.dimensions() != expected) {
        return Err(MetricsError::SizeMismatch {
            what: "the non-occluded mask",
            expected,
            actual: mask.dimensions(),
        });
    }
    let mut sums = RegionSums {
        all: ErrorSums::with_thresholds(thresholds),
        noc: noc.map(|_| ErrorSums::with_thresholds(thresholds)),
        occ: noc.map(|_| ErrorSums::with_thresholds(thresholds)),
    };
    for (i, (&p, &g)) in prediction.as_raw().iter().zip(gt.as_raw()).enumerate() {
        if !g.is_finite() {
            continue;
        }
        sums.all.add(p, g);
        if let Some(mask) = noc {
            let part = if mask.as_raw()[i] != 0 {
                &mut sums.noc
            } else {
                &mut sums.occ
            };
            if let Some(part) = part.as_mut() {
                part.add(p, g);
            }
        }
    }
    Ok(sums)
}

/// Per-image averages of [`Metrics`] over a set: each value is the mean of
/// the images where it is defined, so an image with an empty region does not
/// pull the mean towards zero.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeanMetrics {
    images: u64,
    epe: (f64, u64),
    out: Vec<(f32, f64, u64)>,
    d1: (f64, u64),
    density: (f64, u64),
}

impl MeanMetrics {
    /// An empty average.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the metrics of one image.
    pub fn add(&mut self, m: &Metrics) {
        fn push(acc: &mut (f64, u64), v: Option<f64>) {
            if let Some(v) = v {
                acc.0 += v;
                acc.1 += 1;
            }
        }
        self.images += 1;
        push(&mut self.epe, m.epe);
        push(&mut self.d1, m.d1);
        push(&mut self.density, m.density);
        for &(x, v) in &m.out {
            let slot = match self.out.iter().position(|o| o.0 == x) {
                Some(i) => i,
                None => {
                    self.out.push((x, 0.0, 0));
                    self.out.len() - 1
                }
            };
            if let Some(v) = v {
                self.out[slot].1 += v;
                self.out[slot].2 += 1;
            }
        }
    }

    /// Number of images added.
    pub fn images(&self) -> u64 {
        self.images
    }

    /// The averages, as [`Metrics`] (`pixels` holds the number of images).
    pub fn mean(&self) -> Metrics {
        let avg = |(s, n): (f64, u64)| (n > 0).then(|| s / n as f64);
        Metrics {
            pixels: self.images,
            epe: avg(self.epe),
            out: self.out.iter().map(|&(x, s, n)| (x, avg((s, n)))).collect(),
            d1: avg(self.d1),
            density: avg(self.density),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(w: u32, h: u32, v: Vec<f32>) -> FloatImage {
        FloatImage::from_raw(w, h, v).unwrap()
    }

    fn close(a: Option<f64>, b: f64) -> bool {
        a.is_some_and(|a| (a - b).abs() < 1e-9)
    }

    #[test]
    fn hand_computed_all_region() {
        // errors: 0.5, 1.5, 2.5, 4.0, GT invalid, prediction missing
        let gt = map(6, 1, vec![10.0, 10.0, 10.0, 100.0, f32::INFINITY, 5.0]);
        let pred = map(6, 1, vec![10.5, 8.5, 12.5, 96.0, 3.0, f32::INFINITY]);
        let sums = evaluate(&pred, &gt, None, &DEFAULT_OUT_THRESHOLDS).unwrap();
        let m = sums.all.metrics();
        assert_eq!(m.pixels, 5);
        // EPE over the 4 predicted pixels: (0.5 + 1.5 + 2.5 + 4) / 4.
        assert!(close(m.epe, 8.5 / 4.0));
        // Out-1: 1.5, 2.5, 4, missing -> 4/5; Out-2: 3/5; Out-3: 2/5.
        assert!(close(m.out(1.0), 80.0));
        assert!(close(m.out(2.0), 60.0));
        assert!(close(m.out(3.0), 40.0));
        // D1: 4 px on GT 100 is 4 % < 5 %: not an outlier; only the missing one.
        assert!(close(m.d1, 20.0));
        assert!(close(m.density, 80.0));
        assert!(sums.noc.is_none() && sums.occ.is_none());
        assert_eq!(m.out(1.5), None);
    }

    #[test]
    fn d1_needs_both_three_pixels_and_five_percent() {
        // GT 40: 5 % = 2 px, so 3.5 px is an outlier; GT 80: 5 % = 4 px, so
        // 3.5 px is not; GT 20 with 2.9 px: below 3 px, not an outlier.
        let gt = map(3, 1, vec![40.0, 80.0, 20.0]);
        let pred = map(3, 1, vec![43.5, 76.5, 22.9]);
        let m = evaluate(&pred, &gt, None, &[3.0]).unwrap().all.metrics();
        assert!(close(m.d1, 100.0 / 3.0));
        assert!(close(m.out(3.0), 200.0 / 3.0));
    }

    #[test]
    fn noc_and_occ_split_all() {
        let gt = map(4, 1, vec![1.0, 2.0, 3.0, f32::INFINITY]);
        let pred = map(4, 1, vec![1.0, 5.0, 3.5, 0.0]);
        let noc = MaskImage::from_raw(4, 1, vec![255, 0, 255, 0]).unwrap();
        let sums = evaluate(&pred, &gt, Some(&noc), &[1.0]).unwrap();
        let noc_m = sums.noc.as_ref().unwrap().metrics();
        let occ_m = sums.occ.as_ref().unwrap().metrics();
        assert_eq!((noc_m.pixels, occ_m.pixels), (2, 1));
        assert!(close(noc_m.epe, 0.25));
        assert!(close(occ_m.epe, 3.0));
        assert!(close(occ_m.out(1.0), 100.0));
        assert!(close(sums.all.metrics().epe, 3.5 / 3.0));
    }

    #[test]
    fn empty_sets_give_none() {
        let gt = map(2, 1, vec![f32::INFINITY; 2]);
        let pred = map(2, 1, vec![1.0, 2.0]);
        let all_noc = MaskImage::from_raw(2, 1, vec![255, 255]).unwrap();
        let sums = evaluate(&pred, &gt, Some(&all_noc), &[1.0]).unwrap();
        let m = sums.all.metrics();
        assert_eq!(
            (m.epe, m.d1, m.density, m.out(1.0)),
            (None, None, None, None)
        );
        // Only missing predictions: outliers are defined, EPE is not.
        let gt = map(1, 1, vec![3.0]);
        let pred = map(1, 1, vec![f32::NAN]);
        let m = evaluate(&pred, &gt, None, &[1.0]).unwrap().all.metrics();
        assert_eq!(m.epe, None);
        assert!(close(m.out(1.0), 100.0));
        assert!(MeanMetrics::new().mean().epe.is_none());
    }

    #[test]
    fn pooled_and_per_image_means_differ_as_expected() {
        let thresholds = [2.0];
        let a = evaluate(
            &map(1, 1, vec![1.0]),
            &map(1, 1, vec![2.0]),
            None,
            &thresholds,
        )
        .unwrap();
        let b = evaluate(
            &map(3, 1, vec![0.0, 0.0, 0.0]),
            &map(3, 1, vec![4.0, 4.0, 4.0]),
            None,
            &thresholds,
        )
        .unwrap();
        let mut pooled = RegionSums {
            all: ErrorSums::with_thresholds(&thresholds),
            ..RegionSums::default()
        };
        let mut mean = MeanMetrics::new();
        for s in [&a, &b] {
            pooled.merge(s);
            mean.add(&s.all.metrics());
        }
        // Pooled: (1 + 12) / 4 pixels; per image: (1 + 4) / 2.
        assert!(close(pooled.all.metrics().epe, 13.0 / 4.0));
        assert!(close(mean.mean().epe, 2.5));
        assert!(close(pooled.all.metrics().out(2.0), 75.0));
        assert!(close(mean.mean().out(2.0), 50.0));
        assert_eq!(mean.images(), 2);
    }

    #[test]
    fn default_sums_start_a_pool_with_any_thresholds() {
        // Out-0.5 is not among the default thresholds: the first merge into
        // empty sums must take them from the image.
        let thresholds = [0.5];
        let gt = map(2, 1, vec![2.0, 2.0]);
        let noc = MaskImage::from_raw(2, 1, vec![255, 0]).unwrap();
        let a = evaluate(&map(2, 1, vec![2.0, 3.0]), &gt, Some(&noc), &thresholds).unwrap();
        let b = evaluate(&map(2, 1, vec![2.0, 2.0]), &gt, Some(&noc), &thresholds).unwrap();
        let mut pooled = RegionSums::default();
        pooled.merge(&a);
        assert_eq!(pooled, a);
        pooled.merge(&b);
        // One outlier (the occluded pixel of `a`) in 4 pixels.
        assert!(close(pooled.all.metrics().out(0.5), 25.0));
        assert!(close(
            pooled.get(Region::Occ).unwrap().metrics().out(0.5),
            50.0
        ));
        assert!(close(
            pooled.get(Region::Noc).unwrap().metrics().out(0.5),
            0.0
        ));
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let err = evaluate(
            &map(2, 1, vec![0.0; 2]),
            &map(1, 1, vec![0.0]),
            None,
            &[1.0],
        );
        assert!(matches!(
            err,
            Err(MetricsError::SizeMismatch {
                what: "the prediction",
                ..
            })
        ));
    }
}
