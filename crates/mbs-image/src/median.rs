//! The median filter of a float map (a disparity or depth map): each pixel
//! takes the median of the finite values in the square around it, which
//! removes isolated wrong values and small speckles while keeping the
//! position of depth edges.

use rayon::prelude::*;

use mbs_core::FloatImage;

/// Median of the finite values in the `(2 radius + 1)`-pixel square around
/// each pixel (clipped at the borders; of an even count, the upper of the
/// two middle values). A pixel with no finite value around it keeps its own.
pub fn median_filter(map: &FloatImage, radius: u32) -> FloatImage {
    let (width, height) = map.dimensions();
    let (w, h, r) = (width as usize, height as usize, radius as usize);
    let mut out = map.clone();
    if r == 0 || w == 0 {
        return out;
    }
    let src = map.as_raw();
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let rows = y.saturating_sub(r)..(y + r + 1).min(h);
        let mut window = Vec::with_capacity((2 * r + 1) * (2 * r + 1));
        for (x, value) in row.iter_mut().enumerate() {
            let columns = x.saturating_sub(r)..(x + r + 1).min(w);
            window.clear();
            for yy in rows.clone() {
                let line = &src[yy * w..(yy + 1) * w];
                window.extend(line[columns.clone()].iter().filter(|v| v.is_finite()));
            }
            if window.is_empty() {
                continue;
            }
            let middle = window.len() / 2;
            let (_, median, _) = window.select_nth_unstable_by(middle, f32::total_cmp);
            *value = *median;
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(width: u32, values: &[f32]) -> FloatImage {
        FloatImage::from_raw(width, values.len() as u32 / width, values.to_vec()).unwrap()
    }

    #[test]
    fn an_outlier_goes_and_a_step_edge_stays_in_place() {
        let mut values = vec![2.0; 7 * 5];
        for y in 0..5 {
            for x in 4..7 {
                values[y * 7 + x] = 9.0; // a nearer surface from column 4 on
            }
        }
        values[2 * 7 + 1] = 50.0; // an isolated wrong value
        let filtered = median_filter(&map(7, &values), 1);
        for y in 0..5 {
            for x in 0..7 {
                let expected = if x >= 4 { 9.0 } else { 2.0 };
                assert_eq!(filtered.get_pixel(x, y).0[0], expected, "({x}, {y})");
            }
        }
    }

    #[test]
    fn unknown_values_are_skipped_and_kept_where_nothing_is_known() {
        let inf = f32::INFINITY;
        let filtered = median_filter(&map(4, &[inf, 1.0, 3.0, inf, inf, inf, inf, inf]), 1);
        // Column 0 sees 1 alone, columns 1 and 2 see 1 and 3 (the upper
        // middle is taken), column 3 sees 3 alone; in both rows.
        assert_eq!(filtered.as_raw()[..4], [1.0, 3.0, 3.0, 3.0]);
        assert_eq!(filtered.as_raw()[4..], [1.0, 3.0, 3.0, 3.0]);
        let unknown = map(2, &[inf, inf]);
        assert!(median_filter(&unknown, 2).iter().all(|v| v.is_infinite()));
        assert_eq!(median_filter(&unknown, 0), unknown);
    }
}
