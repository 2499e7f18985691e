//! Backward warping: rebuild the reference view from a target view and the
//! reference disparity by sampling the target at `x -/+ d` (conventions §2) with
//! linear interpolation along the row.

use rayon::prelude::*;

use mbs_core::{FloatImage, MaskImage, RgbImage, Side};

/// Samples `target` at the match of each reference pixel, `x + side.shift(d)`,
/// with linear interpolation. Returns the reconstructed reference view and a
/// mask of the pixels whose disparity was valid and whose match fell inside
/// the target (255), others 0 (left black).
///
/// # Panics
/// When `target` and `disparity` differ in size (a programming error).
pub fn warp_from_target(
    target: &RgbImage,
    disparity: &FloatImage,
    side: Side,
) -> (RgbImage, MaskImage) {
    assert_eq!(
        target.dimensions(),
        disparity.dimensions(),
        "target and disparity sizes differ"
    );
    let (width, height) = target.dimensions();
    let w = width as usize;
    let mut out = RgbImage::new(width, height);
    let mut valid = MaskImage::new(width, height);
    out.par_chunks_mut(w * 3)
        .zip(valid.par_chunks_mut(w))
        .zip(target.par_chunks(w * 3).zip(disparity.par_chunks(w)))
        .for_each(|((dst, ok), (src, disp))| {
            for x in 0..w {
                let d = disp[x];
                if !d.is_finite() {
                    continue;
                }
                let sx = x as f32 + side.shift(d);
                if sx < 0.0 || sx > (w - 1) as f32 {
                    continue;
                }
                let x0 = sx.floor() as usize;
                let x1 = (x0 + 1).min(w - 1);
                let t = sx - x0 as f32;
                for c in 0..3 {
                    let v = f32::from(src[x0 * 3 + c]) * (1.0 - t) + f32::from(src[x1 * 3 + c]) * t;
                    dst[x * 3 + c] = v.round() as u8;
                }
                ok[x] = 255;
            }
        });
    (out, valid)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_disparity_is_identity() {
        let img = RgbImage::from_fn(6, 2, |x, y| image::Rgb([x as u8 * 40, y as u8, 3]));
        let (out, valid) = warp_from_target(&img, &FloatImage::new(6, 2), Side::Right);
        assert_eq!(out, img);
        assert!(valid.as_raw().iter().all(|v| *v == 255));
    }

    #[test]
    fn half_pixel_shift_interpolates_and_marks_outside() {
        let target = RgbImage::from_raw(3, 1, vec![0, 0, 0, 100, 100, 100, 200, 200, 200]).unwrap();
        let disp = FloatImage::from_raw(3, 1, vec![0.5; 3]).unwrap();
        let (out, valid) = warp_from_target(&target, &disp, Side::Right);
        // x = 1 samples x - 0.5 = 0.5 -> 50; x = 0 falls outside.
        assert_eq!(out.get_pixel(1, 0).0, [50, 50, 50]);
        assert_eq!(valid.as_raw(), &vec![0, 255, 255]);
        let (_, valid_left) = warp_from_target(&target, &disp, Side::Left);
        assert_eq!(valid_left.as_raw(), &vec![255, 255, 0]);
    }
}
