//! A plain block matcher: sum of absolute luma differences over a square
//! window, winner-take-all, no refinement. A baseline for comparisons.

use mbs_core::{FloatImage, MaskImage, RgbImage};

use crate::error::{InferError, Result};
use crate::matcher::{Disparity, StereoMatcher, check_same_size, luma};

/// Block matching by SAD on a `window` x `window` luma window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockMatcher {
    /// Largest disparity searched (pixels); disparities `0..max_disparity`.
    pub max_disparity: u32,
    /// Side of the square window (odd).
    pub window: u32,
}

impl Default for BlockMatcher {
    fn default() -> Self {
        Self {
            max_disparity: 64,
            window: 9,
        }
    }
}

impl StereoMatcher for BlockMatcher {
    fn name(&self) -> &str {
        "block-matching"
    }

    fn predict(&self, left: &RgbImage, right: &RgbImage) -> Result<Disparity> {
        check_same_size(left, right)?;
        if self.window.is_multiple_of(2) || self.max_disparity == 0 {
            return Err(InferError::InvalidConfig {
                name: "window / max_disparity",
                value: format!("{} / {}", self.window, self.max_disparity),
                expected: "an odd window and at least one disparity",
            });
        }
        let (w, h) = (left.width() as usize, left.height() as usize);
        let (gl, gr) = (luma(left), luma(right));
        let radius = self.window as usize / 2;
        let mut best_cost = vec![u32::MAX; w * h];
        let mut best = vec![0f32; w * h];
        let mut diff = vec![0u32; w * h];
        for d in 0..(self.max_disparity as usize).min(w) {
            for y in 0..h {
                let (row_l, row_r) = (&gl[y * w..][..w], &gr[y * w..][..w]);
                for x in 0..w {
                    // Columns left of the image match the nearest column.
                    let xr = x.saturating_sub(d);
                    diff[y * w + x] = u32::from(row_l[x].abs_diff(row_r[xr]));
                }
            }
            let sums = box_sum(&diff, w, h, radius);
            for (i, &s) in sums.iter().enumerate() {
                // Disparities beyond the left border are impossible.
                if s < best_cost[i] && d <= i % w {
                    best_cost[i] = s;
                    best[i] = d as f32;
                }
            }
        }
        // `best` holds one value per pixel of the w x h input.
        let disparity =
            FloatImage::from_raw(w as u32, h as u32, best).expect("one value per pixel");
        let valid = MaskImage::from_pixel(w as u32, h as u32, image::Luma([255]));
        Ok(Disparity { disparity, valid })
    }
}

/// Sums over a `(2r+1)^2` window, clamped at the borders.
fn box_sum(values: &[u32], w: usize, h: usize, r: usize) -> Vec<u32> {
    let mut rows = vec![0u32; w * h];
    for (src, dst) in values.chunks_exact(w).zip(rows.chunks_exact_mut(w)) {
        let mut prefix = vec![0u32; w + 1];
        for (x, &v) in src.iter().enumerate() {
            prefix[x + 1] = prefix[x] + v;
        }
        for (x, out) in dst.iter_mut().enumerate() {
            *out = prefix[(x + r + 1).min(w)] - prefix[x.saturating_sub(r)];
        }
    }
    let mut out = vec![0u32; w * h];
    let mut prefix = vec![0u32; (h + 1) * w];
    for y in 0..h {
        for x in 0..w {
            prefix[(y + 1) * w + x] = prefix[y * w + x] + rows[y * w + x];
        }
    }
    for y in 0..h {
        let (lo, hi) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            out[y * w + x] = prefix[hi * w + x] - prefix[lo * w + x];
        }
    }
    out
}
