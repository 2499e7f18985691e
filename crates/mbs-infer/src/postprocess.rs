//! Post-processing shared by matchers: left-right consistency and speckle
//! removal (holes are filled by `mbs_image::fill`). Maps are row-major `f32`
//! slices with `+inf` for "no value".

use rayon::prelude::*;

/// Invalidates left disparities that the right-view disparity does not
/// confirm: the left pixel `x` with disparity `d` lands on right pixel
/// `x - d`; when the right disparity there (at the floor and at the ceiling
/// of `x - d`) differs by more than `max_diff` pixels, `d` is dropped.
/// Pixels whose right partner has no value are kept. Inlined into its
/// caller, so that it is compiled with the caller's target features.
#[inline(always)]
pub fn left_right_check(left: &mut [f32], right: &[f32], width: usize, max_diff: f32) {
    for (row_l, row_r) in left.chunks_exact_mut(width).zip(right.chunks_exact(width)) {
        for (x, d) in row_l.iter_mut().enumerate() {
            let target = x as f32 - *d;
            if !d.is_finite() || target < 0.0 {
                continue;
            }
            // Truncation is the floor for non-negative values.
            let floor = target as usize;
            let ceil = if target > floor as f32 {
                floor + 1
            } else {
                floor
            };
            let disagrees = |xr: usize| {
                row_r
                    .get(xr)
                    .is_some_and(|r| r.is_finite() && (r - *d).abs() > max_diff)
            };
            if disagrees(floor) && disagrees(ceil) {
                *d = f32::INFINITY;
            }
        }
    }
}

/// Removes speckles: 4-connected regions of valid pixels whose neighbours
/// differ by at most `max_step` pixels of disparity, with fewer than
/// `min_size` pixels, become invalid.
///
/// The regions are labelled in a raster pass over a union-find forest of
/// the pixels (a flood fill's stack costs a push, a pop and a division per
/// pixel), one band of rows per thread, the bands then joined along their
/// seams; a second pass counts the regions and a third clears the small
/// ones.
pub fn remove_speckles(map: &mut [f32], width: usize, min_size: usize, max_step: f32) {
    if min_size <= 1 || width == 0 {
        return;
    }
    let bands = rayon::current_num_threads();
    remove_speckles_in_bands(map, width, min_size, max_step, bands);
}

/// [`remove_speckles`] with the labelling split into `bands` bands of rows.
fn remove_speckles_in_bands(
    map: &mut [f32],
    width: usize,
    min_size: usize,
    max_step: f32,
    bands: usize,
) {
    let band = map.len().div_ceil(width).div_ceil(bands).max(1) * width;
    let mut forest = Forest {
        parent: vec![0; map.len()],
        first: 0,
    };
    forest
        .parent
        .par_chunks_mut(band)
        .zip(map.par_chunks(band))
        .enumerate()
        .for_each(|(b, (parent, rows))| {
            let mut part = Forest {
                parent,
                first: b * band,
            };
            part.label(rows, width, max_step);
        });
    for seam in (band..map.len()).step_by(band) {
        for i in seam..(seam + width).min(map.len()) {
            if (map[i] - map[i - width]).abs() <= max_step {
                forest.join(i, i - width);
            }
        }
    }
    let sizes = forest.roots_and_sizes(map);
    map.par_iter_mut()
        .zip(&forest.parent)
        .for_each(|(d, &root)| {
            if d.is_finite() && sizes[root as usize] < min_size as u32 {
                *d = f32::INFINITY;
            }
        });
}

/// Speckle regions as a union-find forest over the pixels `first..` of a
/// map: `parent[i - first] <= i` leads towards the root of pixel `i`'s
/// region, its first pixel in raster order.
struct Forest<P> {
    parent: P,
    first: usize,
}

impl<P: AsMut<[u32]>> Forest<P> {
    /// Labels `rows` (the map's pixels from `first` on): joins each valid
    /// pixel to its valid left and upper neighbours within `max_step`. A
    /// pixel joined to its left neighbour takes its parent, and one joined
    /// to its upper neighbour merges the two regions, unless the 2x2 block
    /// they close is joined all round (the left neighbour's merge made it).
    fn label(&mut self, rows: &[f32], width: usize, max_step: f32) {
        // An invalid pixel (+inf) is never within the step of another.
        let near = |a: f32, b: f32| (a - b).abs() <= max_step;
        for (y, row) in rows.chunks(width).enumerate() {
            let above = (y > 0).then(|| &rows[(y - 1) * width..][..row.len()]);
            for (x, &d) in row.iter().enumerate() {
                let i = y * width + x;
                let left = x > 0 && near(d, row[x - 1]);
                let parent = self.parent.as_mut();
                parent[i] = if left {
                    parent[i - 1]
                } else {
                    (self.first + i) as u32
                };
                let Some(above) = above else { continue };
                if near(d, above[x])
                    && !(left && near(above[x], above[x - 1]) && near(row[x - 1], above[x - 1]))
                {
                    self.join(self.first + i, self.first + i - width);
                }
            }
        }
    }

    /// The root of pixel `i`'s region, halving the path on the way.
    fn root(&mut self, mut i: usize) -> usize {
        let (parent, first) = (self.parent.as_mut(), self.first);
        while parent[i - first] as usize != i {
            let up = parent[i - first] as usize;
            parent[i - first] = parent[up - first];
            i = up;
        }
        i
    }

    /// Merges the regions of pixels `a` and `b` under the earlier root.
    fn join(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.root(a), self.root(b));
        let (keep, merged) = if ra < rb { (ra, rb) } else { (rb, ra) };
        self.parent.as_mut()[merged - self.first] = keep as u32;
    }

    /// Points every pixel of the whole map's forest at its root, and
    /// returns at each root the number of valid pixels of its region, in
    /// one sweep: parents come before their children, so each parent holds
    /// its root when a child reads it.
    fn roots_and_sizes(&mut self, map: &[f32]) -> Vec<u32> {
        let parent = self.parent.as_mut();
        let mut sizes = vec![0u32; map.len()];
        for (i, d) in map.iter().enumerate() {
            let root = parent[parent[i] as usize];
            parent[i] = root;
            sizes[root as usize] += u32::from(d.is_finite());
        }
        sizes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const INF: f32 = f32::INFINITY;

    #[test]
    fn speckles_below_the_size_vanish() {
        // 3x3: a lone 9 in a field of 1s (which join across small steps).
        let mut map = vec![1.0, 1.5, 2.0, 1.0, 9.0, 2.5, 1.0, 1.0, 3.0];
        remove_speckles(&mut map, 3, 2, 1.0);
        assert!(map[4].is_infinite());
        assert_eq!(map.iter().filter(|v| v.is_finite()).count(), 8);
    }

    /// The regions a flood fill finds, as the filter removes them.
    fn flood_fill_reference(map: &mut [f32], width: usize, min_size: usize, max_step: f32) {
        let height = map.len() / width;
        let mut seen = vec![false; map.len()];
        for start in 0..map.len() {
            if seen[start] || !map[start].is_finite() {
                continue;
            }
            seen[start] = true;
            let (mut stack, mut members) = (vec![start], Vec::new());
            while let Some(i) = stack.pop() {
                members.push(i);
                let (x, y) = (i % width, i / width);
                let neighbours = [
                    (x > 0).then(|| i - 1),
                    (x + 1 < width).then(|| i + 1),
                    (y > 0).then(|| i - width),
                    (y + 1 < height).then(|| i + width),
                ];
                for j in neighbours.into_iter().flatten() {
                    if !seen[j] && map[j].is_finite() && (map[j] - map[i]).abs() <= max_step {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
            if members.len() < min_size {
                for i in members {
                    map[i] = INF;
                }
            }
        }
    }

    #[test]
    fn speckle_regions_are_the_flood_fills() {
        // Random maps of a few disparity levels with holes, where regions
        // wind, merge late in raster order (U shapes) and touch the borders.
        let mut state = 0x2545_f491_u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        for (width, height, min_size) in [(1, 9, 3), (9, 1, 3), (17, 13, 4), (40, 30, 12)] {
            let map: Vec<f32> = (0..width * height)
                .map(|_| match next() % 5 {
                    0 => INF,
                    level => level as f32 + (next() % 3) as f32 * 0.25,
                })
                .collect();
            let mut reference = map.clone();
            flood_fill_reference(&mut reference, width, min_size, 1.0);
            let removed = map.iter().zip(&reference).filter(|(a, b)| a != b).count();
            assert!(
                removed > 0 || width * height < 20,
                "{width}x{height}: {removed}"
            );
            // One band, and bands whose seams cut regions.
            for bands in [1, 2, 3, 7] {
                let mut fast = map.clone();
                remove_speckles_in_bands(&mut fast, width, min_size, 1.0, bands);
                assert_eq!(
                    fast, reference,
                    "{width}x{height} in {bands} bands, regions under {min_size}"
                );
            }
        }
    }

    #[test]
    fn left_right_check_drops_disagreeing_pixels() {
        // Left pixel 3 with d = 2 lands on right pixel 1: right says 2, kept.
        // Left pixel 2 with d = 1 lands on right pixel 1: right says 2, dropped.
        let mut left = vec![INF, INF, 1.0, 2.0];
        let right = vec![INF, 2.0, INF, INF];
        left_right_check(&mut left, &right, 4, 0.5);
        assert!(left[2].is_infinite());
        assert_eq!(left[3], 2.0);
    }
}
