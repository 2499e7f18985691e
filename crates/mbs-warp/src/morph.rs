//! Binary mask dilation: square and elliptical structuring elements, and a
//! one-sided horizontal dilation of hole runs towards the background or the
//! foreground side of a depth edge.

use mbs_core::{FloatImage, MaskImage};
use rayon::prelude::*;

use crate::error::{WarpError, check_size};
use crate::forward::SAME_SURFACE_PX;

/// The shape of a structuring element of radius `r` (size `2r + 1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// A `(2r + 1) x (2r + 1)` square (separable: row pass then column pass).
    Square,
    /// A disc: on the row `dy` from the centre, offsets `|dx| <=
    /// round(sqrt(r^2 - dy^2))` (OpenCV's `MORPH_ELLIPSE` of size `2r + 1`).
    Ellipse,
}

/// Dilates `mask` (non-zero = set) by a structuring element of `shape` and
/// `radius`; the result holds 255 where set. Radius 0 copies the mask.
pub fn dilate(mask: &MaskImage, shape: Shape, radius: u32) -> MaskImage {
    let (width, height) = mask.dimensions();
    // A radius beyond the u16 distance range covers any image anyway.
    let r = (radius as usize).min(usize::from(u16::MAX - 1));
    let (w, h) = (width as usize, height as usize);
    let mut out = MaskImage::new(width, height);
    if w == 0 || h == 0 {
        return out;
    }
    // Horizontal distance (capped at r + 1) to the nearest set pixel of the row.
    let mut hdist = vec![0u16; w * h];
    let cap = (r + 1) as u16;
    hdist
        .par_chunks_mut(w)
        .zip(mask.par_chunks(w))
        .for_each(|(dist, row)| row_distance(row, dist, cap));
    // Half-width of the element on the row `dy` away from the centre.
    let half_width: Vec<u16> = (0..=r)
        .map(|dy| match shape {
            Shape::Square => r as u16,
            Shape::Ellipse => ((r * r - dy * dy) as f64).sqrt().round() as u16,
        })
        .collect();
    out.par_chunks_mut(w).enumerate().for_each(|(y, dst)| {
        let y0 = y.saturating_sub(r);
        let y1 = (y + r).min(h - 1);
        for (yy, dist) in hdist.chunks(w).enumerate().take(y1 + 1).skip(y0) {
            let reach = half_width[yy.abs_diff(y)];
            for (o, &d) in dst.iter_mut().zip(dist) {
                if d <= reach {
                    *o = 255;
                }
            }
        }
    });
    out
}

/// Per pixel of `row`, the distance to the nearest set pixel, capped at `cap`.
fn row_distance(row: &[u8], dist: &mut [u16], cap: u16) {
    let mut last = cap;
    for (d, &m) in dist.iter_mut().zip(row) {
        last = if m != 0 {
            0
        } else {
            last.saturating_add(1).min(cap)
        };
        *d = last;
    }
    last = cap;
    for (d, &m) in dist.iter_mut().zip(row).rev() {
        last = if m != 0 {
            0
        } else {
            last.saturating_add(1).min(cap)
        };
        *d = (*d).min(last);
    }
}

/// Which side of a hole at a depth edge a one-sided dilation grows into.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeSide {
    /// The farther surface (smaller disparity) next to the hole.
    Background,
    /// The nearer surface (larger disparity) next to the hole. When an
    /// estimated disparity is too large on background pixels next to a depth
    /// edge ("edge fattening"), those pixels travel with the foreground and
    /// land on this side of the disocclusion.
    Foreground,
}

/// Grows each horizontal run of set pixels in `holes` by `radius` pixels on
/// one side only, chosen by `towards` from the warped `disparity` of the two
/// pixels bordering the run. Runs between two pixels of one surface
/// (disparities within [`SAME_SURFACE_PX`]) or touching the image border are
/// not a depth discontinuity and stay as they are.
pub fn dilate_one_side(
    holes: &MaskImage,
    disparity: &FloatImage,
    radius: u32,
    towards: EdgeSide,
) -> Result<MaskImage, WarpError> {
    check_size("disparity", holes.dimensions(), disparity.dimensions())?;
    let mut out = holes.clone();
    let w = holes.width() as usize;
    if w == 0 {
        return Ok(out);
    }
    let r = radius as usize;
    out.par_chunks_mut(w)
        .zip(holes.par_chunks(w).zip(disparity.par_chunks(w)))
        .for_each(|(dst, (src, disp))| {
            for (start, end) in runs(src) {
                if start == 0 || end == w {
                    continue;
                }
                let (left, right) = (disp[start - 1], disp[end]);
                if !left.is_finite() || !right.is_finite() || (left - right).abs() < SAME_SURFACE_PX
                {
                    continue;
                }
                let grow_left = (left < right) == (towards == EdgeSide::Background);
                if grow_left {
                    dst[start.saturating_sub(r)..start].fill(255);
                } else {
                    dst[end..(end + r).min(w)].fill(255);
                }
            }
        });
    Ok(out)
}

/// The maximal runs `[start, end)` of non-zero values in `row`.
pub(crate) fn runs(row: &[u8]) -> impl Iterator<Item = (usize, usize)> + '_ {
    let mut x = 0;
    std::iter::from_fn(move || {
        while x < row.len() && row[x] == 0 {
            x += 1;
        }
        if x == row.len() {
            return None;
        }
        let start = x;
        while x < row.len() && row[x] != 0 {
            x += 1;
        }
        Some((start, x))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn single_dot(size: u32, x: u32, y: u32) -> MaskImage {
        let mut m = MaskImage::new(size, size);
        m.put_pixel(x, y, image::Luma([255]));
        m
    }

    fn set_offsets(mask: &MaskImage, cx: i64, cy: i64) -> Vec<(i64, i64)> {
        mask.enumerate_pixels()
            .filter(|(_, _, p)| p.0[0] == 255)
            .map(|(x, y, _)| (i64::from(x) - cx, i64::from(y) - cy))
            .collect()
    }

    #[test]
    fn square_dilation_of_a_dot_is_a_square_clipped_at_the_border() {
        let out = dilate(&single_dot(9, 4, 4), Shape::Square, 2);
        let set = set_offsets(&out, 4, 4);
        assert_eq!(set.len(), 25);
        assert!(set.iter().all(|(dx, dy)| dx.abs() <= 2 && dy.abs() <= 2));
        let corner = dilate(&single_dot(9, 0, 0), Shape::Square, 2);
        assert_eq!(set_offsets(&corner, 0, 0).len(), 9);
    }

    #[test]
    fn ellipse_dilation_of_a_dot_matches_opencv_disc() {
        // cv2.getStructuringElement(MORPH_ELLIPSE, (7, 7)) has rows of
        // half-widths 0, 2, 3, 3, 3, 2, 0 (from the top): 29 pixels.
        let out = dilate(&single_dot(11, 5, 5), Shape::Ellipse, 3);
        let set = set_offsets(&out, 5, 5);
        let row_width = |dy: i64| set.iter().filter(|(_, y)| *y == dy).count();
        let widths: Vec<usize> = (-3..=3).map(row_width).collect();
        assert_eq!(widths, vec![1, 5, 7, 7, 7, 5, 1]);
    }

    #[test]
    fn radius_zero_and_empty_masks() {
        let dot = single_dot(5, 1, 3);
        assert_eq!(dilate(&dot, Shape::Ellipse, 0), dot);
        let empty = MaskImage::new(6, 4);
        assert_eq!(dilate(&empty, Shape::Square, 3), empty);
    }

    #[test]
    fn one_sided_dilation_grows_towards_the_chosen_surface() {
        // Row: background d = 2 | hole 4..6 | foreground d = 9.
        let holes = MaskImage::from_raw(10, 1, vec![0, 0, 0, 0, 255, 255, 0, 0, 0, 0]).unwrap();
        let disp = FloatImage::from_fn(10, 1, |x, _| {
            image::Luma([if x < 4 {
                2.0
            } else if x < 6 {
                f32::INFINITY
            } else {
                9.0
            }])
        });
        let out = dilate_one_side(&holes, &disp, 3, EdgeSide::Background).unwrap();
        assert_eq!(out.as_raw(), &vec![0, 255, 255, 255, 255, 255, 0, 0, 0, 0]);
        // Mirrored scene: the growth goes right.
        let mirrored = MaskImage::from_raw(10, 1, vec![0, 0, 0, 0, 255, 255, 0, 0, 0, 0]).unwrap();
        let disp_m =
            FloatImage::from_fn(10, 1, |x, _| image::Luma([if x < 4 { 9.0 } else { 2.0 }]));
        let out_m = dilate_one_side(&mirrored, &disp_m, 3, EdgeSide::Background).unwrap();
        assert_eq!(
            out_m.as_raw(),
            &vec![0, 0, 0, 0, 255, 255, 255, 255, 255, 0]
        );
    }

    #[test]
    fn one_sided_dilation_leaves_cracks_and_borders_alone() {
        let holes = MaskImage::from_raw(8, 1, vec![255, 0, 0, 255, 0, 0, 0, 255]).unwrap();
        let disp =
            FloatImage::from_raw(8, 1, vec![5.0, 5.0, 5.2, 5.0, 5.4, 5.0, 5.0, 5.0]).unwrap();
        let out = dilate_one_side(&holes, &disp, 2, EdgeSide::Foreground).unwrap();
        assert_eq!(out, holes);
    }
}
