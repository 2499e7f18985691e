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
pub fn remove_speckles(map: &mut [f32], width: usize, min_size: usize, max_step: f32) {
    if min_size <= 1 || width == 0 {
        return;
    }
    let height = map.len() / width;
    const UNSEEN: u32 = u32::MAX;
    let mut label = vec![UNSEEN; map.len()];
    let mut stack = Vec::new();
    let mut members = Vec::new();
    let mut next = 0u32;
    for start in 0..map.len() {
        if label[start] != UNSEEN || !map[start].is_finite() {
            continue;
        }
        label[start] = next;
        stack.push(start);
        members.clear();
        while let Some(i) = stack.pop() {
            members.push(i);
            let (x, y) = (i % width, i / width);
            let d = map[i];
            let mut visit = |j: usize| {
                if label[j] == UNSEEN && map[j].is_finite() && (map[j] - d).abs() <= max_step {
                    label[j] = next;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < width {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - width);
            }
            if y + 1 < height {
                visit(i + width);
            }
        }
        if members.len() < min_size {
            for &i in &members {
                map[i] = f32::INFINITY;
            }
        }
        next += 1;
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
