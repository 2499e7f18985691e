//! Forward warping (splatting) of a view by its own disparity, with a z-buffer.
//!
//! Each row is warped on its own. Neighbouring source pixels whose disparities
//! differ by less than [`SAME_SURFACE_PX`] belong to one surface: the segment
//! between their warped positions is filled by linear interpolation of colour
//! and disparity, so a stretched or sub-pixel-shifted surface leaves no cracks.
//! The first and last pixel of a surface cover half a pixel on their free side,
//! so an integer shift moves every pixel to exactly one target pixel. Where
//! several surfaces land on one target pixel the nearest (largest disparity)
//! wins; on equal disparity the leftmost source pixel wins.

use mbs_core::{FloatImage, MaskImage, RgbImage, Side};
use rayon::prelude::*;

use crate::error::{WarpError, check_size};

/// Two neighbouring pixels whose disparities differ by less than this (px)
/// are taken to lie on one surface (no depth discontinuity between them).
pub const SAME_SURFACE_PX: f32 = 1.0;

/// The result of a forward warp, on the target grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Warped {
    /// The warped view; holes are black.
    pub image: RgbImage,
    /// 255 where nothing landed (disocclusions and the entering border), else 0.
    pub holes: MaskImage,
    /// The disparity of the winning surface at each target pixel; `+inf` in holes.
    pub disparity: FloatImage,
}

/// Warps `image` by its own `disparity` (px, `+inf` = invalid, not splatted)
/// towards a camera on `side` of it, at the same baseline: a pixel at `x`
/// lands at `x + side.shift(d)`.
pub fn forward_warp(
    image: &RgbImage,
    disparity: &FloatImage,
    side: Side,
) -> Result<Warped, WarpError> {
    check_size("disparity", image.dimensions(), disparity.dimensions())?;
    let (width, height) = image.dimensions();
    let w = width as usize;
    let mut out = RgbImage::new(width, height);
    let mut holes = MaskImage::new(width, height);
    let mut warped_disp = FloatImage::new(width, height);
    if w == 0 {
        return Ok(Warped {
            image: out,
            holes,
            disparity: warped_disp,
        });
    }
    out.par_chunks_mut(w * 3)
        .zip(holes.par_chunks_mut(w))
        .zip(warped_disp.par_chunks_mut(w))
        .zip(image.par_chunks(w * 3).zip(disparity.par_chunks(w)))
        .for_each(|(((dst, hole), zbuf), (src, disp))| {
            zbuf.fill(f32::NEG_INFINITY);
            let mut row = RowSplat { dst, zbuf };
            warp_row(src, disp, side, &mut row);
            for (h, z) in hole.iter_mut().zip(row.zbuf.iter_mut()) {
                if *z == f32::NEG_INFINITY {
                    *h = 255;
                    *z = f32::INFINITY;
                }
            }
        });
    Ok(Warped {
        image: out,
        holes,
        disparity: warped_disp,
    })
}

/// One target row being written: colours and the z-buffer (disparity of the
/// current winner, `-inf` where nothing landed yet).
struct RowSplat<'a> {
    dst: &'a mut [u8],
    zbuf: &'a mut [f32],
}

/// One end of a splatted segment: warped position, colour, disparity.
#[derive(Clone, Copy)]
struct End {
    t: f32,
    rgb: [f32; 3],
    d: f32,
}

impl RowSplat<'_> {
    /// Fills the target pixels `x` with `from.t <= x < to.t` (when `lerp`,
    /// interpolating between the ends; else with `from`'s values), keeping
    /// per pixel the largest disparity.
    #[inline(always)]
    fn segment(&mut self, from: End, to: End, lerp: bool) {
        let w = self.zbuf.len();
        let start = ceil_index(from.t).max(0) as usize;
        let stop = (ceil_index(to.t).max(0) as usize).min(w);
        if start >= stop {
            return;
        }
        let inv_span = if lerp { 1.0 / (to.t - from.t) } else { 0.0 };
        for x in start..stop {
            let a = (x as f32 - from.t) * inv_span;
            let d = from.d + (to.d - from.d) * a;
            if d > self.zbuf[x] {
                self.zbuf[x] = d;
                let px = &mut self.dst[x * 3..x * 3 + 3];
                for ((o, f), t) in px.iter_mut().zip(from.rgb).zip(to.rgb) {
                    // Rounds half up; a convex combination stays in 0..=255.
                    *o = (f + (t - f) * a + 0.5) as u8;
                }
            }
        }
    }
}

/// `ceil(t)` as an integer, without the libm call that `f32::ceil` costs
/// on baseline x86-64 (`as` truncates towards zero and saturates).
fn ceil_index(t: f32) -> i64 {
    let i = t as i64;
    if (i as f32) < t {
        i.saturating_add(1)
    } else {
        i
    }
}

/// The colour of pixel `i` of an RGB row, as floats.
#[inline(always)]
fn pixel_rgb(src: &[u8], i: usize) -> [f32; 3] {
    let p = &src[i * 3..i * 3 + 3];
    [f32::from(p[0]), f32::from(p[1]), f32::from(p[2])]
}

/// Splats one source row into `row`: each valid pixel covers half a pixel
/// on a free side, and the segment to its right neighbour when both lie on
/// one surface. (Written with explicit indices: measured faster than the
/// iterator form.)
fn warp_row(src: &[u8], disp: &[f32], side: Side, row: &mut RowSplat<'_>) {
    let sign = side.shift(1.0);
    // Pixel x's end, already computed when pixel x - 1 joined it.
    let mut here: Option<End> = None;
    let mut x = 0usize;
    let w = disp.len();
    while x < w {
        let d = disp[x];
        if !d.is_finite() {
            x += 1;
            continue;
        }
        let this = match here.take() {
            Some(joined) => joined,
            None => {
                let this = End {
                    t: x as f32 + sign * d,
                    rgb: pixel_rgb(src, x),
                    d,
                };
                row.segment(
                    End {
                        t: this.t - 0.5,
                        ..this
                    },
                    this,
                    false,
                );
                this
            }
        };
        let next = if x + 1 < w {
            disp[x + 1]
        } else {
            f32::INFINITY
        };
        if next.is_finite() && (d - next).abs() < SAME_SURFACE_PX {
            let there = End {
                t: (x + 1) as f32 + sign * next,
                rgb: pixel_rgb(src, x + 1),
                d: next,
            };
            row.segment(this, there, true);
            here = Some(there);
        } else {
            row.segment(
                this,
                End {
                    t: this.t + 0.5,
                    ..this
                },
                false,
            );
        }
        x += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ramp(width: u32, height: u32) -> RgbImage {
        RgbImage::from_fn(width, height, |x, y| {
            image::Rgb([(x * 20 % 256) as u8, (y * 30 % 256) as u8, 100])
        })
    }

    fn constant(width: u32, height: u32, d: f32) -> FloatImage {
        FloatImage::from_pixel(width, height, image::Luma([d]))
    }

    #[test]
    fn zero_disparity_is_identity_both_ways() {
        let img = ramp(9, 4);
        for side in [Side::Left, Side::Right] {
            let out = forward_warp(&img, &constant(9, 4, 0.0), side).unwrap();
            assert_eq!(out.image, img);
            assert!(out.holes.as_raw().iter().all(|h| *h == 0));
            assert!(out.disparity.as_raw().iter().all(|d| *d == 0.0));
        }
    }

    #[test]
    fn constant_disparity_is_a_shift_with_holes_at_the_entering_border() {
        let img = ramp(10, 2);
        let right = forward_warp(&img, &constant(10, 2, 3.0), Side::Right).unwrap();
        let left = forward_warp(&img, &constant(10, 2, 3.0), Side::Left).unwrap();
        for y in 0..2 {
            for x in 0..10u32 {
                // Right target: x -> x - 3, so the last 3 columns are holes.
                let hole_r = x >= 7;
                assert_eq!(right.holes.get_pixel(x, y).0[0] == 255, hole_r, "x={x}");
                if !hole_r {
                    assert_eq!(right.image.get_pixel(x, y), img.get_pixel(x + 3, y));
                    assert_eq!(right.disparity.get_pixel(x, y).0[0], 3.0);
                } else {
                    assert_eq!(right.disparity.get_pixel(x, y).0[0], f32::INFINITY);
                }
                // Left target: x -> x + 3, so the first 3 columns are holes.
                let hole_l = x < 3;
                assert_eq!(left.holes.get_pixel(x, y).0[0] == 255, hole_l, "x={x}");
                if !hole_l {
                    assert_eq!(left.image.get_pixel(x, y), img.get_pixel(x - 3, y));
                }
            }
        }
    }

    #[test]
    fn half_pixel_shift_interpolates_without_cracks() {
        let src = RgbImage::from_raw(
            4,
            1,
            vec![0, 0, 0, 100, 100, 100, 200, 200, 200, 40, 40, 40],
        )
        .unwrap();
        let out = forward_warp(&src, &constant(4, 1, 0.5), Side::Right).unwrap();
        // Source x lands at x - 0.5: target 0 is midway between sources 0 and 1.
        assert_eq!(out.image.get_pixel(0, 0).0, [50, 50, 50]);
        assert_eq!(out.image.get_pixel(1, 0).0, [150, 150, 150]);
        assert_eq!(out.image.get_pixel(2, 0).0, [120, 120, 120]);
        // The last source pixel covers [2.5, 3) and no pixel centre: target 3
        // is the entering border.
        assert_eq!(out.holes.as_raw(), &vec![0, 0, 0, 255]);
    }

    #[test]
    fn nearer_surface_occludes_farther_one() {
        // Background d = 1 everywhere except a foreground block d = 4 at 4..6.
        let width = 12;
        let img = RgbImage::from_fn(width, 1, |x, _| {
            if (4..6).contains(&x) {
                image::Rgb([255, 0, 0])
            } else {
                image::Rgb([0, 0, (x * 10) as u8])
            }
        });
        let disp = FloatImage::from_fn(width, 1, |x, _| {
            image::Luma([if (4..6).contains(&x) { 4.0 } else { 1.0 }])
        });
        let out = forward_warp(&img, &disp, Side::Left).unwrap();
        // Foreground lands at 8..10 and hides the background from 7 and 8 that
        // would land there; background 3 -> 4 and 6 -> 7 leave holes at 5, 6.
        for x in 8..10 {
            assert_eq!(out.image.get_pixel(x, 0).0, [255, 0, 0], "x={x}");
            assert_eq!(out.disparity.get_pixel(x, 0).0[0], 4.0);
        }
        let holes: Vec<u32> = (0..width)
            .filter(|&x| out.holes.get_pixel(x, 0).0[0] == 255)
            .collect();
        assert_eq!(holes, vec![0, 5, 6]);
        // Background after the block: source 10 -> 11.
        assert_eq!(out.image.get_pixel(11, 0).0, [0, 0, 100]);
    }

    #[test]
    fn slanted_plane_warps_without_cracks() {
        // Disparity grows 0.6 px per column: the warped surface stretches by
        // 1.6 and must stay closed.
        let width = 40;
        let img = ramp(width, 3);
        let disp = FloatImage::from_fn(width, 3, |x, _| image::Luma([0.6 * x as f32]));
        let out = forward_warp(&img, &disp, Side::Left).unwrap();
        for y in 0..3 {
            for x in 0..width {
                // Source 0 covers [-0.5, 0); source 39 lands at 62.4 > width.
                assert_eq!(out.holes.get_pixel(x, y).0[0], 0, "crack at x={x}");
                // Warped disparity of target x solves x = s + 0.6 s.
                let d = out.disparity.get_pixel(x, y).0[0];
                assert!((d - 0.6 * x as f32 / 1.6).abs() < 1e-4, "x={x} d={d}");
            }
        }
    }

    #[test]
    fn ceil_index_matches_ceil() {
        for t in [
            -2.0f32,
            -1.5,
            -0.5,
            -0.0,
            0.0,
            0.25,
            1.0,
            1.5,
            2.999,
            1e6 + 0.5,
        ] {
            assert_eq!(ceil_index(t), t.ceil() as i64, "t={t}");
        }
    }

    #[test]
    fn absurd_disparities_leave_the_image_without_panicking() {
        let img = ramp(4, 1);
        let disp = FloatImage::from_raw(4, 1, vec![1e30, -1e30, f32::NAN, f32::MAX]).unwrap();
        for side in [Side::Left, Side::Right] {
            let out = forward_warp(&img, &disp, side).unwrap();
            assert!(out.holes.as_raw().iter().all(|h| *h == 255));
        }
    }

    #[test]
    fn invalid_disparity_is_not_splatted() {
        let img = ramp(5, 1);
        let disp = FloatImage::from_raw(5, 1, vec![0.0, 0.0, f32::INFINITY, 0.0, 0.0]).unwrap();
        let out = forward_warp(&img, &disp, Side::Right).unwrap();
        assert_eq!(out.holes.as_raw(), &vec![0, 0, 255, 0, 0]);
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let err = forward_warp(&ramp(4, 4), &constant(4, 3, 0.0), Side::Left).unwrap_err();
        assert!(err.to_string().contains("disparity is (4, 3)"), "{err}");
    }

    proptest! {
        #[test]
        fn zero_disparity_identity_holds_for_any_image(
            width in 1u32..24,
            height in 1u32..6,
            seed in any::<u64>(),
            right in any::<bool>(),
        ) {
            let img = RgbImage::from_fn(width, height, |x, y| {
                let v = seed.wrapping_mul(u64::from(x * 31 + y * 7 + 1)).wrapping_add(seed >> 7);
                image::Rgb([v as u8, (v >> 8) as u8, (v >> 16) as u8])
            });
            let side = if right { Side::Right } else { Side::Left };
            let out = forward_warp(&img, &constant(width, height, 0.0), side).unwrap();
            prop_assert_eq!(out.image, img);
            prop_assert!(out.holes.as_raw().iter().all(|h| *h == 0));
        }
    }
}
