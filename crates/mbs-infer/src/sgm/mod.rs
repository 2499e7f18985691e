//! The built-in semi-global matcher (Hirschmüller 2008): sparse census
//! matching cost, 5- or 8-path aggregation with penalties P1/P2, winner-take-all
//! with parabola sub-pixel refinement, left-right consistency check,
//! speckle removal and a background-side fill of the holes.
//!
//! Rows are processed in independent bands (in parallel with rayon), each
//! with a few extra rows above (and below, for 8 paths) to warm up the
//! vertical paths. Memory does not grow with the image height: 5-path
//! aggregation keeps one row of `i16` costs per band, 8-path one band. The band layout is fixed by the configuration, so the
//! result does not depend on the number of threads.

mod aggregate;
mod census;
mod estimate;
mod select;

pub use estimate::estimate_max_disparity;

use mbs_core::{FloatImage, MaskImage, RgbImage, Side};
use rayon::prelude::*;

use crate::error::{InferError, Result};
use crate::matcher::{Disparity, StereoMatcher, check_same_size, luma, predict_mirrored};
use crate::postprocess::{left_right_check, remove_speckles};
use aggregate::{BandInput, RowSink, aggregate_band};
use mbs_image::fill::fill_row_from_background;

/// Which aggregation paths run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SgmPaths {
    /// Left-to-right, right-to-left and the three top-down directions
    /// (vertical and both diagonals): one pass over the rows, as OpenCV's
    /// `StereoSGBM` in its default and 3-way modes.
    Five,
    /// The five above plus the three bottom-up directions: the full 8-path
    /// SGM, about 1.6 times the time.
    Eight,
}

/// Settings of [`Sgm`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SgmConfig {
    /// Number of disparities searched: `0..max_disparity` pixels; 0
    /// estimates it per pair ([`estimate_max_disparity`], up to
    /// [`MAX_ESTIMATED_DISPARITY`]).
    pub max_disparity: u32,
    /// Census window width (odd). The census samples every other pixel of
    /// the window (see [`samples_of`]), at most 32 of them: 9x7 gives 32.
    pub census_width: u32,
    /// Census window height (odd).
    pub census_height: u32,
    /// Penalty for a disparity change of one pixel along a path.
    pub p1: u16,
    /// Penalty for larger disparity changes along a path.
    pub p2: u16,
    /// Aggregation paths.
    pub paths: SgmPaths,
    /// Uniqueness margin in percent (0 disables): the best cost must beat
    /// every cost more than one disparity away by this margin.
    pub uniqueness: u32,
    /// Largest left-right disagreement kept, in pixels (`None` disables the
    /// check).
    pub lr_max_diff: Option<f32>,
    /// Regions smaller than this many pixels are removed as speckles
    /// (0 disables).
    pub speckle_size: usize,
    /// Largest disparity step inside one speckle region, in pixels.
    pub speckle_range: f32,
    /// Fill holes from the background side (see
    /// [`mbs_image::fill::fill_row_from_background`]).
    pub fill: bool,
    /// Rows per band (the unit of parallel work).
    pub band_rows: u32,
    /// Extra rows that warm up the vertical paths of each band.
    pub band_overlap: u32,
}

impl Default for SgmConfig {
    fn default() -> Self {
        Self {
            max_disparity: 128,
            census_width: 9,
            census_height: 7,
            // Tuned on Middlebury Teddy and Tsukuba (9x7 census costs 0..32).
            p1: 5,
            p2: 20,
            paths: SgmPaths::Five,
            uniqueness: 10,
            lr_max_diff: Some(1.0),
            speckle_size: 100,
            speckle_range: 2.0,
            fill: true,
            band_rows: 96,
            band_overlap: 16,
        }
    }
}

/// The most disparities the matcher searches (its costs fit in `i16`).
pub const MAX_DISPARITY: u32 = 4096;

impl SgmConfig {
    /// The default settings with `max_disparity` disparities.
    pub fn with_max_disparity(max_disparity: u32) -> Self {
        Self {
            max_disparity,
            ..Self::default()
        }
    }

    fn validate(&self) -> Result<()> {
        let invalid = |name, value: String, expected| InferError::InvalidConfig {
            name,
            value,
            expected,
        };
        if self.max_disparity > MAX_DISPARITY {
            return Err(invalid(
                "max_disparity",
                self.max_disparity.to_string(),
                "0 (estimate per pair) to 4096",
            ));
        }
        let (cw, ch) = (self.census_width, self.census_height);
        let odd_and_small = |side: u32| side % 2 == 1 && side <= 15;
        if !odd_and_small(cw) || !odd_and_small(ch) || !(1..=32).contains(&samples_of(cw, ch)) {
            return Err(invalid(
                "census window",
                format!("{cw}x{ch}"),
                "odd sides giving 1 to 32 samples (3x3 to 9x7)",
            ));
        }
        // Path costs stay below cost + P2 <= 32 + P2; eight of them must fit
        // in i16 next to the padding.
        if self.p1 == 0 || self.p1 > self.p2 || self.p2 > 1900 {
            return Err(invalid(
                "p1 / p2",
                format!("{} / {}", self.p1, self.p2),
                "0 < p1 <= p2 <= 1900",
            ));
        }
        if self.band_rows == 0 {
            return Err(invalid("band_rows", "0".into(), "at least 1"));
        }
        Ok(())
    }
}

/// Number of pixels a census over a `width` x `height` window compares
/// with its centre: every other pixel (a checkerboard with the corners).
pub fn samples_of(width: u32, height: u32) -> usize {
    census::samples(width as usize, height as usize).len()
}

/// The largest disparity range estimated per pair when
/// [`SgmConfig::max_disparity`] is 0.
pub const MAX_ESTIMATED_DISPARITY: u32 = 256;

/// Semi-global matching with census costs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sgm {
    /// The settings.
    pub config: SgmConfig,
}

impl Sgm {
    /// A matcher with the given settings.
    pub fn new(config: SgmConfig) -> Self {
        Self { config }
    }

    /// The matcher with its range fixed for the pair `(left, right)`:
    /// a `max_disparity` of 0 is estimated from this pair, in this order,
    /// so that both views' disparities of a pair search the same range.
    fn for_pair(&self, left: &RgbImage, right: &RgbImage) -> Result<Sgm> {
        if self.config.max_disparity != 0 {
            return Ok(*self);
        }
        let max_disparity = estimate_max_disparity(left, right, MAX_ESTIMATED_DISPARITY)?;
        Ok(Sgm::new(SgmConfig {
            max_disparity,
            ..self.config
        }))
    }

    /// Left disparities after selection and the left-right check but before
    /// speckle removal and filling (`+inf` = rejected).
    fn raw_disparity(&self, left: &RgbImage, right: &RgbImage) -> Result<Vec<f32>> {
        self.raw_disparity_on(pulp::Arch::new(), left, right)
    }

    /// [`Sgm::raw_disparity`] with the vector instructions of `arch`.
    fn raw_disparity_on(
        &self,
        arch: pulp::Arch,
        left: &RgbImage,
        right: &RgbImage,
    ) -> Result<Vec<f32>> {
        let c = &self.config;
        let (w, h) = (left.width() as usize, left.height() as usize);
        if w == 0 || h == 0 {
            return Err(InferError::TooSmall {
                size: left.dimensions(),
                min: (1, 1),
                what: "matching",
            });
        }
        let (cw, ch) = (c.census_width as usize, c.census_height as usize);
        let num_disp = (c.max_disparity as usize).min(w);
        let (gl, gr) = rayon::join(|| luma(left), || luma(right));
        let (census_l, census_r) = rayon::join(
            || census::census(&gl, w, cw, ch),
            || census::census(&gr, w, cw, ch),
        );
        let right_planes = census::reversed_planes(&census_r, w);
        let input = BandInput {
            left: &census_l,
            right_planes: &right_planes,
            size: (w, h),
            num_disp,
            invalid_cost: census::samples(cw, ch).len() as u8,
            penalties: (c.p1 as i16, c.p2 as i16),
            overlap: c.band_overlap as usize,
            bottom_up: c.paths == SgmPaths::Eight,
        };
        let band = c.band_rows as usize * w;
        let mut disp_l = vec![f32::INFINITY; w * h];
        let mut disp_r = vec![f32::INFINITY; w * h];
        disp_l
            .par_chunks_mut(band)
            .zip(disp_r.par_chunks_mut(band))
            .enumerate()
            .for_each(|(b, (out_l, out_r))| {
                let y0 = b * c.band_rows as usize;
                let rows = y0..y0 + out_l.len() / w;
                arch.dispatch(MatchBand {
                    input: &input,
                    rows,
                    out_l,
                    out_r,
                    config: c,
                });
            });
        Ok(disp_l)
    }
}

/// The matching of one band of rows: aggregation, selection and the
/// left-right check, into the band's rows of both disparity maps.
///
/// Run through [`pulp::Arch::dispatch`]: on a processor with AVX2 (x86-64-v3)
/// the whole band, every function it calls being inlined, is compiled for
/// it, so the `i16` and byte loops vectorise 16 and 32 lanes wide instead of
/// the portable build's 8 and 16; elsewhere it runs the portable code. The
/// arithmetic is the same integer arithmetic either way, so the results are
/// identical.
struct MatchBand<'a> {
    input: &'a BandInput<'a>,
    rows: std::ops::Range<usize>,
    out_l: &'a mut [f32],
    out_r: &'a mut [f32],
    config: &'a SgmConfig,
}

impl pulp::WithSimd for MatchBand<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let w = self.input.size.0;
        let mut selection = Selection {
            width: w,
            uniqueness: self.config.uniqueness,
            out_l: self.out_l,
            out_r: self.out_r,
            scratch: select::Scratch::default(),
        };
        aggregate_band(self.input, self.rows, &mut selection);
        if let Some(max_diff) = self.config.lr_max_diff {
            left_right_check(selection.out_l, selection.out_r, w, max_diff);
        }
    }
}

/// The disparities of a band's rows, selected as their costs are summed.
struct Selection<'a> {
    width: usize,
    uniqueness: u32,
    out_l: &'a mut [f32],
    out_r: &'a mut [f32],
    scratch: select::Scratch,
}

impl RowSink for Selection<'_> {
    #[inline(always)]
    fn row(&mut self, i: usize, sums: &[i16]) {
        let w = self.width;
        let (l, r) = (&mut self.out_l[i * w..][..w], &mut self.out_r[i * w..][..w]);
        select::select_row(sums, self.uniqueness, l, r, &mut self.scratch);
    }
}

impl StereoMatcher for Sgm {
    fn name(&self) -> &str {
        "sgm"
    }

    fn predict(&self, left: &RgbImage, right: &RgbImage) -> Result<Disparity> {
        check_same_size(left, right)?;
        self.config.validate()?;
        self.for_pair(left, right)?.match_fixed(left, right)
    }

    fn predict_right(&self, left: &RgbImage, right: &RgbImage) -> Result<Disparity> {
        check_same_size(left, right)?;
        self.config.validate()?;
        predict_mirrored(&self.for_pair(left, right)?, left, right)
    }

    fn predict_toward_within(
        &self,
        reference: &RgbImage,
        target: &RgbImage,
        side: Side,
        bound: u32,
    ) -> Result<Disparity> {
        let within = Sgm::new(SgmConfig {
            max_disparity: bound.min(MAX_DISPARITY),
            ..self.config
        });
        within.predict_toward(reference, target, side)
    }
}

impl Sgm {
    /// [`StereoMatcher::predict`] with a fixed (non-zero) range.
    fn match_fixed(&self, left: &RgbImage, right: &RgbImage) -> Result<Disparity> {
        let (w, h) = left.dimensions();
        let mut disp = self.raw_disparity(left, right)?;
        remove_speckles(
            &mut disp,
            w as usize,
            self.config.speckle_size,
            self.config.speckle_range,
        );
        let valid: Vec<u8> = disp
            .iter()
            .map(|d| if d.is_finite() { 255 } else { 0 })
            .collect();
        if self.config.fill {
            disp.par_chunks_mut(w as usize)
                .for_each(fill_row_from_background);
        }
        Ok(Disparity {
            // Both buffers hold one value per pixel of the w x h input.
            disparity: FloatImage::from_raw(w, h, disp).expect("one value per pixel"),
            valid: MaskImage::from_raw(w, h, valid).expect("one value per pixel"),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_vector_and_portable_builds_match_alike() {
        // A textured pair shifted by 5 px; 40 disparities (not a multiple
        // of the vector width) and both path counts.
        let texture = |x: u32, y: u32| {
            let v = (x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(40_503)) >> 7;
            image::Rgb([v as u8, (v >> 8) as u8, (x * 7 + y * 3) as u8])
        };
        let left = RgbImage::from_fn(77, 40, texture);
        let right = RgbImage::from_fn(77, 40, |x, y| texture(x + 5, y));
        for paths in [SgmPaths::Five, SgmPaths::Eight] {
            let sgm = Sgm::new(SgmConfig {
                max_disparity: 40,
                paths,
                band_rows: 16,
                ..SgmConfig::default()
            });
            let vector = sgm
                .raw_disparity_on(pulp::Arch::new(), &left, &right)
                .unwrap();
            let portable = sgm
                .raw_disparity_on(pulp::Arch::Scalar, &left, &right)
                .unwrap();
            assert_eq!(vector, portable, "{paths:?}");
            let found = vector.iter().filter(|d| (**d - 5.0).abs() < 0.5).count();
            assert!(
                found > vector.len() / 2,
                "{found} of {} at the shift",
                vector.len()
            );
        }
    }
}
