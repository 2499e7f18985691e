//! The [`StereoMatcher`] trait: a rectified pair in, a disparity on the
//! reference grid out.

use image::imageops;
use mbs_core::{FloatImage, MaskImage, RgbImage, Side};

use crate::error::{InferError, Result};

/// A disparity map with the pixels a matcher trusts.
#[derive(Debug, Clone, PartialEq)]
pub struct Disparity {
    /// Disparity in pixels on the reference grid, `+inf` where there is no
    /// value at all. Matchers that fill holes leave it finite everywhere.
    pub disparity: FloatImage,
    /// 255 where the value was matched and passed the matcher's checks, 0
    /// where it was filled in or is missing.
    pub valid: MaskImage,
}

impl Disparity {
    /// The map mirrored horizontally (column `x` goes to `width - 1 - x`).
    pub fn mirrored(&self) -> Disparity {
        Disparity {
            disparity: imageops::flip_horizontal(&self.disparity),
            valid: imageops::flip_horizontal(&self.valid),
        }
    }
}

/// Dense stereo matching on rectified pairs.
pub trait StereoMatcher: Send + Sync {
    /// A short name for logs and tables.
    fn name(&self) -> &str;

    /// Disparity of the `left` view, with `right` as target: a left pixel at
    /// column `x` is seen in `right` at `x - d` (conventions §2). The views must
    /// have the same size.
    fn predict(&self, left: &RgbImage, right: &RgbImage) -> Result<Disparity>;

    /// Disparity of the `right` view, with `left` as target (a right pixel
    /// at `x` is seen in `left` at `x + d`): both views are mirrored, their
    /// roles swapped, and the result mirrored back (conventions §2).
    fn predict_right(&self, left: &RgbImage, right: &RgbImage) -> Result<Disparity> {
        predict_mirrored(self, left, right)
    }

    /// Disparity of `reference` with `target` on `side` of it: the one
    /// entry point for pairs whose target may lie on either side
    /// ([`StereoMatcher::predict`] or [`StereoMatcher::predict_right`]).
    fn predict_toward(
        &self,
        reference: &RgbImage,
        target: &RgbImage,
        side: Side,
    ) -> Result<Disparity> {
        match side {
            Side::Right => self.predict(reference, target),
            Side::Left => self.predict_right(target, reference),
        }
    }

    /// [`StereoMatcher::predict_toward`] for a pair whose disparities are
    /// known to lie in `0..bound` (a benchmark's `ndisp`): a matcher that
    /// searches a fixed range of disparities searches this one instead;
    /// networks, which have no such range, ignore it.
    fn predict_toward_within(
        &self,
        reference: &RgbImage,
        target: &RgbImage,
        side: Side,
        bound: u32,
    ) -> Result<Disparity> {
        let _ = bound;
        self.predict_toward(reference, target, side)
    }
}

/// An [`InferError::NoPrediction`] when a network's map `disparity` holds
/// a NaN or no finite value at all (broken weights, a diverged run): such
/// a map must never be written as a result. (The built-in matcher may
/// rightly find no match at all on a featureless pair.)
pub fn check_values(matcher: &str, disparity: &FloatImage) -> Result<()> {
    let nan = disparity.iter().filter(|d| d.is_nan()).count();
    let finite = disparity.iter().filter(|d| d.is_finite()).count();
    let problem = if nan > 0 {
        format!("{nan} of its {} values are NaN", disparity.len())
    } else if finite == 0 {
        "it has no finite value".to_string()
    } else {
        return Ok(());
    };
    Err(InferError::NoPrediction {
        matcher: matcher.to_string(),
        problem,
    })
}

/// The `right` view's disparity by `matcher`: both views mirrored, their
/// roles swapped, and the result mirrored back.
pub fn predict_mirrored<M: StereoMatcher + ?Sized>(
    matcher: &M,
    left: &RgbImage,
    right: &RgbImage,
) -> Result<Disparity> {
    check_same_size(left, right)?;
    let mirrored_right = imageops::flip_horizontal(right);
    let mirrored_left = imageops::flip_horizontal(left);
    Ok(matcher.predict(&mirrored_right, &mirrored_left)?.mirrored())
}

/// An [`InferError::SizeMismatch`] unless both views have the same size.
pub fn check_same_size(left: &RgbImage, right: &RgbImage) -> Result<()> {
    if left.dimensions() == right.dimensions() {
        Ok(())
    } else {
        Err(InferError::SizeMismatch {
            left: left.dimensions(),
            right: right.dimensions(),
        })
    }
}

/// The luma of an RGB image (ITU-R BT.601 weights, rounded), row-major.
pub fn luma(image: &RgbImage) -> Vec<u8> {
    image
        .pixels()
        .map(|p| {
            let [r, g, b] = p.0.map(u32::from);
            ((77 * r + 150 * g + 29 * b + 128) >> 8) as u8
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_map_with_nan_or_nothing_finite_is_not_a_prediction() {
        let map = |values: Vec<f32>| FloatImage::from_raw(2, 2, values).unwrap();
        assert!(check_values("m", &map(vec![1.0, f32::INFINITY, 0.0, 2.5])).is_ok());
        let err = check_values("net", &map(vec![1.0, f32::NAN, f32::NAN, 2.5]))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("net gave no usable disparity: 2 of its 4 values are NaN"),
            "{err}"
        );
        let err = check_values("net", &map(vec![f32::INFINITY; 4]))
            .unwrap_err()
            .to_string();
        assert!(err.contains("it has no finite value"), "{err}");
    }
}
