//! Filling invalid pixels of a disparity map from the background side: the
//! disparity of a disoccluded or unknown pixel is that of the farther
//! (smaller-disparity) surface next to it.

use mbs_core::FloatImage;
use mbs_image::fill::fill_row_from_background;
use rayon::prelude::*;

/// Fills each horizontal run of invalid (non-finite) pixels with the smaller
/// of the valid disparities on its two sides (the only one at an image
/// border; see [`fill_row_from_background`]). Rows without any valid pixel then copy the nearest row that has
/// one (the one above on a tie); a map without any valid pixel is returned
/// as it is.
///
/// This turns a forward-warped disparity into a complete one for the target
/// view (e.g. the right view's disparity from the left view's), and fills
/// the unknown border of a ground-truth map.
pub fn fill_disparity_background(disparity: &FloatImage) -> FloatImage {
    let mut out = disparity.clone();
    let w = disparity.width() as usize;
    if w == 0 {
        return out;
    }
    out.par_chunks_mut(w).for_each(fill_row_from_background);
    let valid_rows: Vec<usize> = out
        .chunks(w)
        .enumerate()
        .filter(|(_, row)| row[0].is_finite())
        .map(|(y, _)| y)
        .collect();
    if valid_rows.is_empty() {
        return out;
    }
    let filled = out.as_raw().clone();
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        if !row[0].is_finite() {
            let nearest = valid_rows.partition_point(|&v| v < y);
            let above = nearest.checked_sub(1).map(|i| valid_rows[i]);
            let below = valid_rows.get(nearest).copied();
            let from = match (above, below) {
                (Some(a), Some(b)) if b - y < y - a => b,
                (Some(a), _) => a,
                (None, Some(b)) => b,
                (None, None) => return,
            };
            row.copy_from_slice(&filled[from * w..(from + 1) * w]);
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fills_runs_with_the_farther_side_and_borders_with_the_neighbour() {
        let inf = f32::INFINITY;
        #[rustfmt::skip]
        let d = FloatImage::from_raw(4, 4, vec![
            inf, inf, inf, inf,
            3.0, inf, inf, 7.0,
            inf, inf, inf, inf,
            inf, 5.0, 6.0, inf,
        ])
        .unwrap();
        let out = fill_disparity_background(&d);
        // Row 1: the run between 3 and 7 takes 3. Row 3: borders copy.
        // Rows 0 and 2 copy the nearest valid row (above on a tie).
        let row1 = [3.0, 3.0, 3.0, 7.0];
        let row3 = [5.0, 5.0, 6.0, 6.0];
        assert_eq!(out.as_raw(), &[row1, row1, row1, row3].concat());
        let none = FloatImage::from_pixel(3, 2, image::Luma([inf]));
        assert_eq!(fill_disparity_background(&none), none);
    }
}
