//! Semi-global cost aggregation over one band of rows: the path recurrence
//!
//! `L(p, d) = C(p, d) + min(L(p-r, d), L(p-r, d±1) + P1, min L(p-r) + P2) - min L(p-r)`
//!
//! along horizontal, vertical and diagonal paths, summed into `i16` costs
//! with the disparity dimension contiguous so the inner loops vectorise.

use std::ops::Range;

use super::census::cost_row;

/// Padding value around each pixel's path costs: large, but far enough from
/// `i16::MAX` that adding `P1` cannot overflow.
const BIG: i16 = i16::MAX / 2;

/// What the aggregation of one band needs.
pub struct BandInput<'a> {
    /// Left census signatures, row-major.
    pub left: &'a [u32],
    /// Right census signatures as reversed byte planes.
    pub right_planes: &'a [u8],
    /// Image width and height.
    pub size: (usize, usize),
    /// Number of disparities `D`.
    pub num_disp: usize,
    /// Cost of disparities past the left border.
    pub invalid_cost: u8,
    /// Small and large smoothness penalties.
    pub penalties: (i16, i16),
    /// Rows above (and below, with bottom-up paths) the band that warm up
    /// the vertical and diagonal paths.
    pub overlap: usize,
    /// Whether to add the three bottom-up paths (8 paths instead of 5).
    pub bottom_up: bool,
}

/// Aggregates the costs of the output `rows` and hands each row's summed
/// costs (`width * D`, `sums[x * D + d]`) to `emit` with its index in the
/// band. With top-down paths only, rows are emitted as they are done and
/// only one row of sums is kept; with bottom-up paths the band's sums are
/// kept until the second pass ends.
pub fn aggregate_band(input: &BandInput, rows: Range<usize>, mut emit: impl FnMut(usize, &[i16])) {
    let (w, h) = input.size;
    let nd = input.num_disp;
    let row_len = w * nd;
    let kept_rows = if input.bottom_up { rows.len() } else { 1 };
    let mut sums = vec![0i16; kept_rows * row_len];
    let mut cost = vec![0u8; row_len];
    let mut paths = Paths::new(w, nd, input.penalties);
    let cost_of = |y: usize, cost: &mut [u8]| {
        cost_row(
            &input.left[y * w..][..w],
            &input.right_planes[4 * y * w..][..4 * w],
            input.invalid_cost,
            cost,
        );
    };
    for y in rows.start.saturating_sub(input.overlap)..rows.end {
        cost_of(y, &mut cost);
        if y < rows.start {
            paths.vertical::<false, false>(&cost, &mut []);
            continue;
        }
        let i = y - rows.start;
        let out = if input.bottom_up {
            &mut sums[i * row_len..][..row_len]
        } else {
            sums.fill(0);
            &mut sums[..]
        };
        paths.vertical::<true, true>(&cost, out);
        paths.right_to_left(&cost, out);
        if !input.bottom_up {
            emit(i, out);
        }
    }
    if input.bottom_up {
        paths.restart();
        for y in (rows.start..(rows.end + input.overlap).min(h)).rev() {
            cost_of(y, &mut cost);
            if y < rows.end {
                let out = &mut sums[(y - rows.start) * row_len..][..row_len];
                paths.vertical::<true, false>(&cost, out);
            } else {
                paths.vertical::<false, false>(&cost, &mut []);
            }
        }
        for (i, row) in sums.chunks_exact(row_len).enumerate() {
            emit(i, row);
        }
    }
}

/// Path costs of one direction on the previous and the current row.
struct RowPair {
    prev: Vec<i16>,
    prev_min: Vec<i16>,
    cur: Vec<i16>,
    cur_min: Vec<i16>,
}

/// State of the paths along one pass over the rows.
struct Paths {
    width: usize,
    num_disp: usize,
    penalties: (i16, i16),
    /// The three vertical directions, from `x - 1`, `x` and `x + 1` on the
    /// previous row.
    rows: [RowPair; 3],
    /// No previous row yet.
    fresh: bool,
    /// Path costs before the first pixel: zero, padded.
    start: Vec<i16>,
    /// Two pixels of horizontal path costs (previous and current).
    scratch: [Vec<i16>; 2],
}

impl Paths {
    fn new(width: usize, num_disp: usize, penalties: (i16, i16)) -> Self {
        let stride = num_disp + 2;
        let pair = || RowPair {
            prev: vec![BIG; width * stride],
            prev_min: vec![0; width],
            cur: vec![BIG; width * stride],
            cur_min: vec![0; width],
        };
        let mut start = vec![0; stride];
        start[0] = BIG;
        start[stride - 1] = BIG;
        Self {
            width,
            num_disp,
            penalties,
            rows: [pair(), pair(), pair()],
            fresh: true,
            scratch: [vec![BIG; stride], vec![BIG; stride]],
            start,
        }
    }

    /// Starts a new pass (the vertical paths forget the previous row).
    fn restart(&mut self) {
        self.fresh = true;
    }

    /// Advances the three vertical paths by one row of `cost`, with the
    /// left-to-right path of the row when `LEFT_TO_RIGHT`, adding them into
    /// `sums` when `ADD` (one pass over `sums` for all of them).
    fn vertical<const ADD: bool, const LEFT_TO_RIGHT: bool>(
        &mut self,
        cost: &[u8],
        sums: &mut [i16],
    ) {
        let (w, nd) = (self.width, self.num_disp);
        let stride = nd + 2;
        let fresh = self.fresh;
        let [lr_prev, lr_cur] = &mut self.scratch;
        lr_prev.copy_from_slice(&self.start);
        let mut lr_min = 0;
        for x in 0..w {
            let cost = &cost[x * nd..][..nd];
            for (k, pair) in self.rows.iter_mut().enumerate() {
                let from = (x + k).checked_sub(1).filter(|&p| p < w && !fresh);
                let (prev, prev_min) = match from {
                    Some(p) => (&pair.prev[p * stride..][..stride], pair.prev_min[p]),
                    None => (&self.start[..], 0),
                };
                pair.cur_min[x] = step::<false>(
                    cost,
                    prev,
                    prev_min,
                    self.penalties,
                    &mut pair.cur[x * stride..][..stride],
                    &mut [],
                );
            }
            if LEFT_TO_RIGHT {
                lr_min = step::<false>(cost, lr_prev, lr_min, self.penalties, lr_cur, &mut []);
            }
            if ADD {
                let [a, b, c] = &self.rows;
                let start = x * stride + 1;
                let (a, b, c) = (
                    &a.cur[start..][..nd],
                    &b.cur[start..][..nd],
                    &c.cur[start..][..nd],
                );
                let sums = &mut sums[x * nd..][..nd];
                if LEFT_TO_RIGHT {
                    let lr = &lr_cur[1..][..nd];
                    for (d, s) in sums.iter_mut().enumerate() {
                        *s += a[d] + b[d] + c[d] + lr[d];
                    }
                } else {
                    for (d, s) in sums.iter_mut().enumerate() {
                        *s += a[d] + b[d] + c[d];
                    }
                }
            }
            if LEFT_TO_RIGHT {
                std::mem::swap(lr_prev, lr_cur);
            }
        }
        for pair in &mut self.rows {
            std::mem::swap(&mut pair.prev, &mut pair.cur);
            std::mem::swap(&mut pair.prev_min, &mut pair.cur_min);
        }
        self.fresh = false;
    }

    /// Runs the right-to-left path of one row of `cost`, adding it into
    /// `sums`.
    fn right_to_left(&mut self, cost: &[u8], sums: &mut [i16]) {
        let nd = self.num_disp;
        let [a, b] = &mut self.scratch;
        a.copy_from_slice(&self.start);
        let mut prev_min = 0;
        for x in (0..self.width).rev() {
            prev_min = step::<true>(
                &cost[x * nd..][..nd],
                a,
                prev_min,
                self.penalties,
                b,
                &mut sums[x * nd..][..nd],
            );
            std::mem::swap(a, b);
        }
    }
}

/// One step of the path recurrence for all disparities: `prev` and `out`
/// hold `D + 2` values (padding at both ends), `cost` and `sum` hold `D`.
/// Returns the minimum of the new path costs.
#[inline(always)]
fn step<const ADD: bool>(
    cost: &[u8],
    prev: &[i16],
    prev_min: i16,
    (p1, p2): (i16, i16),
    out: &mut [i16],
    sum: &mut [i16],
) -> i16 {
    let n = cost.len();
    let (lower, same, upper) = (&prev[..n], &prev[1..n + 1], &prev[2..n + 2]);
    let out = &mut out[1..n + 1];
    let jump = prev_min + p2;
    let mut best = i16::MAX;
    if ADD {
        let sum = &mut sum[..n];
        for d in 0..n {
            let m = same[d].min(lower[d].min(upper[d]) + p1).min(jump);
            let v = i16::from(cost[d]) + m - prev_min;
            out[d] = v;
            sum[d] += v;
            best = best.min(v);
        }
    } else {
        for d in 0..n {
            let m = same[d].min(lower[d].min(upper[d]) + p1).min(jump);
            let v = i16::from(cost[d]) + m - prev_min;
            out[d] = v;
            best = best.min(v);
        }
    }
    best
}
