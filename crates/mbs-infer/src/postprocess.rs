//! Post-processing shared by matchers: left-right consistency and speckle
//! removal (holes are filled by `mbs_image::fill`). Maps are row-major `f32`
//! slices with `+inf` for "no value".

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
/// The regions are labelled in one raster pass over a union-find forest of
/// the pixels (a flood fill's stack costs a push, a pop and a division per
/// pixel), then counted and cleared in a second.
pub fn remove_speckles(map: &mut [f32], width: usize, min_size: usize, max_step: f32) {
    if min_size <= 1 || width == 0 {
        return;
    }
    let (roots, sizes) = Regions::of(map, width, max_step).into_roots_and_sizes(map);
    for (d, &root) in map.iter_mut().zip(&roots) {
        if d.is_finite() && sizes[root as usize] < min_size as u32 {
            *d = f32::INFINITY;
        }
    }
}

/// The speckle regions of a map as a union-find forest over its pixels:
/// `parent[i] <= i` leads towards the root of `i`'s region, its first pixel
/// in raster order.
struct Regions {
    parent: Vec<u32>,
}

impl Regions {
    /// Joins every valid pixel of `map` to its valid left and upper
    /// neighbours within `max_step`: a pixel joined to its left neighbour
    /// takes its parent, and one joined to its upper neighbour merges the
    /// two regions, unless the 2x2 block they close is joined all round
    /// (then the left neighbour's merge already made it).
    fn of(map: &[f32], width: usize, max_step: f32) -> Self {
        let mut regions = Regions {
            parent: Vec::with_capacity(map.len()),
        };
        // An invalid pixel (+inf) is never within the step of another.
        let near = |a: f32, b: f32| (a - b).abs() <= max_step;
        for (y, row) in map.chunks(width).enumerate() {
            let above = (y > 0).then(|| &map[(y - 1) * width..][..row.len()]);
            for (x, &d) in row.iter().enumerate() {
                let i = y * width + x;
                let left = x > 0 && near(d, row[x - 1]);
                let parent = if left {
                    regions.parent[i - 1]
                } else {
                    i as u32
                };
                regions.parent.push(parent);
                let Some(above) = above else { continue };
                if near(d, above[x])
                    && !(left && near(above[x], above[x - 1]) && near(row[x - 1], above[x - 1]))
                {
                    regions.join(i, i - width);
                }
            }
        }
        regions
    }

    /// The root of pixel `i`'s region, halving the path on the way.
    fn root(&mut self, mut i: usize) -> usize {
        while self.parent[i] as usize != i {
            let up = self.parent[i] as usize;
            self.parent[i] = self.parent[up];
            i = up;
        }
        i
    }

    /// Merges the regions of `a` and `b` under the earlier root.
    fn join(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.root(a), self.root(b));
        let (keep, merged) = if ra < rb { (ra, rb) } else { (rb, ra) };
        self.parent[merged] = keep as u32;
    }

    /// Each pixel's root, and at each root the number of valid pixels of its
    /// region, in one sweep: parents come before their children, so each
    /// parent already holds its root when a child reads it.
    fn into_roots_and_sizes(mut self, map: &[f32]) -> (Vec<u32>, Vec<u32>) {
        let mut sizes = vec![0u32; map.len()];
        for (i, d) in map.iter().enumerate() {
            let root = self.parent[self.parent[i] as usize];
            self.parent[i] = root;
            sizes[root as usize] += u32::from(d.is_finite());
        }
        (self.parent, sizes)
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
            let (mut fast, mut reference) = (map.clone(), map.clone());
            remove_speckles(&mut fast, width, min_size, 1.0);
            flood_fill_reference(&mut reference, width, min_size, 1.0);
            assert_eq!(
                fast, reference,
                "{width}x{height}, regions under {min_size}"
            );
            let removed = map.iter().zip(&fast).filter(|(a, b)| a != b).count();
            assert!(
                removed > 0 || width * height < 20,
                "{width}x{height}: {removed}"
            );
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
