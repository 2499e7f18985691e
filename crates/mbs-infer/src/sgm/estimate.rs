//! A cheap estimate of the disparity range of a pair: SGM on a 4x smaller
//! pair, the 99.5th percentile of what it matched, scaled back up.

use image::imageops::{self, FilterType};
use mbs_core::RgbImage;

use super::{Sgm, SgmConfig};
use crate::error::Result;
use crate::matcher::{StereoMatcher, check_same_size};

/// Downscaling factor of the estimate.
const FACTOR: u32 = 4;

/// Estimates how many disparities a pair needs, searching at most `upper`:
/// the 99.5th percentile of the disparities matched on a 4x smaller pair,
/// plus 10 % and one coarse pixel of margin, rounded up to a multiple of 16
/// and clamped to `16..=upper`. Costs about 1/64 of a full-size match.
pub fn estimate_max_disparity(left: &RgbImage, right: &RgbImage, upper: u32) -> Result<u32> {
    check_same_size(left, right)?;
    let (w, h) = left.dimensions();
    let (sw, sh) = ((w / FACTOR).max(1), (h / FACTOR).max(1));
    let small_l = imageops::resize(left, sw, sh, FilterType::Triangle);
    let small_r = imageops::resize(right, sw, sh, FilterType::Triangle);
    let config = SgmConfig {
        max_disparity: upper.div_ceil(FACTOR).max(1),
        census_width: 5,
        census_height: 5,
        speckle_size: 10,
        fill: false,
        ..SgmConfig::default()
    };
    let coarse = Sgm::new(config).predict(&small_l, &small_r)?;
    let mut values: Vec<f32> = coarse
        .disparity
        .as_raw()
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .collect();
    if values.is_empty() {
        return Ok(upper);
    }
    let rank = (values.len() - 1) * 995 / 1000;
    let (_, &mut high, _) = values.select_nth_unstable_by(rank, f32::total_cmp);
    let estimate = ((high + 1.0) * FACTOR as f32 * 1.1).ceil() as u32;
    Ok(estimate.next_multiple_of(16).clamp(16.min(upper), upper))
}
