//! Disparity selection from aggregated costs: winner-take-all with a
//! uniqueness test and parabola sub-pixel refinement for the left view, and
//! the right-view disparity read off the same costs (the minimum along each
//! diagonal `x - d = const`).

/// Reused buffers: per right-view pixel (reversed), the lowest cost seen
/// along its diagonal and its disparity; and the ramp `0, 1, …, D - 1`.
#[derive(Debug, Default)]
pub struct Scratch {
    cost: Vec<i16>,
    disparity: Vec<i16>,
    ramp: Vec<i16>,
}

/// Selects the disparities of one row from its aggregated costs
/// (`sums[x * D + d]`). `left` gets sub-pixel disparities (`+inf` where the
/// uniqueness test fails), `right` integer right-view disparities (`+inf`
/// where no left pixel maps). `uniqueness` is a percentage: the best cost
/// must beat every cost more than one disparity away by that margin
/// (0 disables the test). `scratch` is reused between rows. Inlined into
/// its caller, so that it is compiled with the caller's target features.
#[inline(always)]
pub fn select_row(
    sums: &[i16],
    uniqueness: u32,
    left: &mut [f32],
    right: &mut [f32],
    scratch: &mut Scratch,
) {
    let width = left.len();
    let num_disp = sums.len() / width;
    scratch.cost.clear();
    scratch.cost.resize(width, i16::MAX);
    scratch.disparity.clear();
    scratch.disparity.resize(width, -1);
    if scratch.ramp.len() != num_disp {
        // D <= 4096 (checked by the configuration), so it fits in i16.
        scratch.ramp = (0..num_disp as i16).collect();
    }
    for (x, s) in sums.chunks_exact(num_disp).enumerate() {
        // Only disparities that stay inside the right view.
        let n = num_disp.min(x + 1);
        let s = &s[..n];
        // A vectorised minimum, then the first disparity that reaches it.
        let cost = s.iter().fold(i16::MAX, |m, &c| m.min(c));
        let d = first_index_of(s, cost);
        // Right pixel x - k sees cost s[k]; strict `<` keeps the smallest
        // disparity on ties. Branch-free so that it vectorises.
        let start = width - 1 - x;
        let min_cost = &mut scratch.cost[start..][..n];
        let min_disp = &mut scratch.disparity[start..][..n];
        let ramp = &scratch.ramp[..n];
        for k in 0..n {
            let mask = -i16::from(s[k] < min_cost[k]);
            min_disp[k] = (ramp[k] & mask) | (min_disp[k] & !mask);
            min_cost[k] = min_cost[k].min(s[k]);
        }
        if uniqueness > 0 {
            let below = &s[..d.saturating_sub(1)];
            let above = s.get(d + 2..).unwrap_or(&[]);
            let min = |part: &[i16]| part.iter().fold(i16::MAX, |m, &c| m.min(c));
            let second = min(below).min(min(above));
            let margin = i64::from(100 - uniqueness.min(100));
            if i64::from(second) * margin < i64::from(cost) * 100 {
                left[x] = f32::INFINITY;
                continue;
            }
        }
        left[x] = d as f32 + subpixel_offset(s, d);
    }
    for (r, &d) in right.iter_mut().zip(scratch.disparity.iter().rev()) {
        *r = if d < 0 { f32::INFINITY } else { f32::from(d) };
    }
}

/// The first index of `value` in `costs` (0 if absent): looked for 16 at a
/// time with a branch-free test that vectorises, then within the block that
/// holds it.
#[inline(always)]
fn first_index_of(costs: &[i16], value: i16) -> usize {
    const BLOCK: usize = 16;
    let block = costs
        .chunks(BLOCK)
        .position(|b| b.iter().fold(false, |found, &c| found | (c == value)))
        .unwrap_or(0);
    let base = block * BLOCK;
    let within = costs[base..].iter().position(|&c| c == value);
    within.map_or(0, |i| base + i)
}

/// Offset in `(-0.5, 0.5)` of the minimum of the parabola through the costs
/// at `d - 1`, `d`, `d + 1`; zero at the ends of the range or on a flat
/// neighbourhood.
#[inline(always)]
fn subpixel_offset(costs: &[i16], d: usize) -> f32 {
    if d == 0 || d + 1 >= costs.len() {
        return 0.0;
    }
    let (a, b, c) = (
        f32::from(costs[d - 1]),
        f32::from(costs[d]),
        f32::from(costs[d + 1]),
    );
    let curvature = a + c - 2.0 * b;
    if curvature <= 0.0 {
        0.0
    } else {
        ((a - c) / (2.0 * curvature)).clamp(-0.5, 0.5)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parabola_vertex_is_found() {
        // Costs of (d - 1.25)^2 * 4 at d = 0, 1, 2: 6.25, 0.25, 2.25.
        let costs = [625, 25, 225];
        let off = subpixel_offset(&costs, 1);
        assert!((off - 0.25).abs() < 1e-6, "{off}");
        assert_eq!(subpixel_offset(&costs, 0), 0.0);
    }

    #[test]
    fn winner_and_right_view_and_uniqueness() {
        // Width 3, 3 disparities. x = 2 prefers d = 2 (right pixel 0),
        // x = 1 prefers d = 0 (right pixel 1), x = 0 can only have d = 0.
        let sums = [5, 9, 9, 1, 8, 9, 9, 9, 2];
        let (mut left, mut right) = (vec![0.0; 3], vec![0.0; 3]);
        select_row(&sums, 0, &mut left, &mut right, &mut Scratch::default());
        assert_eq!(left, vec![0.0, 0.0, 2.0]);
        // Right pixel 0: candidates (x=0,d=0) cost 5, (x=1,d=1) cost 8 and
        // (x=2,d=2) cost 2; right pixel 2 has only (x=2,d=0).
        assert_eq!(right, vec![2.0, 0.0, 0.0]);
        // x = 2: best 10 at d = 0, but 11 at d = 2 is within 10 %: rejected.
        let sums = [0, 0, 0, 0, 0, 0, 10, 30, 11];
        let (mut left, mut right) = (vec![0.0; 3], vec![0.0; 3]);
        select_row(&sums, 10, &mut left, &mut right, &mut Scratch::default());
        assert_eq!(&left[..2], &[0.0, 0.0]);
        assert!(left[2].is_infinite());
        select_row(&sums, 5, &mut left, &mut right, &mut Scratch::default());
        assert_eq!(left[2], 0.0);
    }
}
