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
/// costs (`width * D`, `sums[x * D + d]`) to `sink` with its index in the
/// band. With top-down paths only, rows are emitted as they are done and
/// only one row of sums is kept; with bottom-up paths the band's sums are
/// kept until the second pass ends. Inlined into its caller, so that it is
/// compiled with the caller's target features.
#[inline(always)]
pub fn aggregate_band(input: &BandInput, rows: Range<usize>, sink: &mut impl RowSink) {
    let (w, h) = input.size;
    let nd = input.num_disp;
    let row_len = w * nd;
    let kept_rows = if input.bottom_up { rows.len() } else { 1 };
    let mut sums = vec![0i16; kept_rows * row_len];
    let mut cost = vec![0u8; row_len];
    let mut paths = Paths::new(w, nd, input.penalties);
    for y in rows.start.saturating_sub(input.overlap)..rows.end {
        input.cost_row(y, &mut cost);
        if y < rows.start {
            paths.vertical::<false, false>(&cost, &mut []);
            continue;
        }
        let i = y - rows.start;
        let out = if input.bottom_up {
            &mut sums[i * row_len..][..row_len]
        } else {
            &mut sums[..]
        };
        paths.vertical::<true, true>(&cost, out);
        paths.right_to_left(&cost, out);
        if !input.bottom_up {
            sink.row(i, out);
        }
    }
    if input.bottom_up {
        paths.restart();
        for y in (rows.start..(rows.end + input.overlap).min(h)).rev() {
            input.cost_row(y, &mut cost);
            if y < rows.end {
                let out = &mut sums[(y - rows.start) * row_len..][..row_len];
                paths.vertical::<true, false>(&cost, out);
            } else {
                paths.vertical::<false, false>(&cost, &mut []);
            }
        }
        for (i, row) in sums.chunks_exact(row_len).enumerate() {
            sink.row(i, row);
        }
    }
}

/// Where [`aggregate_band`] hands the summed costs of each row. A trait
/// with an inlined method rather than a closure: a closure would be
/// compiled on its own, without the target features of the band's caller.
pub trait RowSink {
    /// Takes the summed costs of row `i` of the band (`sums[x * D + d]`).
    fn row(&mut self, i: usize, sums: &[i16]);
}

impl BandInput<'_> {
    /// The matching costs of image row `y` into `cost` (`width * D`).
    #[inline(always)]
    fn cost_row(&self, y: usize, cost: &mut [u8]) {
        let w = self.size.0;
        cost_row(
            &self.left[y * w..][..w],
            &self.right_planes[4 * y * w..][..4 * w],
            self.invalid_cost,
            cost,
        );
    }
}

/// Path costs of one direction on the previous and the current row.
struct RowPair {
    prev: Vec<i16>,
    prev_min: Vec<i16>,
    cur: Vec<i16>,
    cur_min: Vec<i16>,
}

/// The path costs (padded) and their minimum at column `from` of the
/// previous row (`prev`, `prev_min`), or the start of a path where there is
/// none.
#[inline(always)]
fn previous<'a>(
    (prev, prev_min): (&'a [i16], &[i16]),
    from: Option<usize>,
    start: &'a [i16],
    stride: usize,
) -> (&'a [i16], i16) {
    match from {
        Some(p) => (&prev[p * stride..][..stride], prev_min[p]),
        None => (start, 0),
    }
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
    /// left-to-right path of the row when `LEFT_TO_RIGHT`, and when `ADD`
    /// sums them into `sums` (one pass over `sums` for all of them). The
    /// top-down pass (`LEFT_TO_RIGHT`) is the first to reach a row: it
    /// writes `sums`; the bottom-up pass adds to them.
    #[inline(always)]
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
            let [a, b, c] = &mut self.rows;
            let before = |k: usize| (x + k).checked_sub(1).filter(|&p| p < w && !fresh);
            let start = &self.start[..];
            let (pa, ma) = previous((&a.prev, &a.prev_min), before(0), start, stride);
            let (pb, mb) = previous((&b.prev, &b.prev_min), before(1), start, stride);
            let (pc, mc) = previous((&c.prev, &c.prev_min), before(2), start, stride);
            let [oa, ob, oc] = [
                &mut a.cur[x * stride..][..stride],
                &mut b.cur[x * stride..][..stride],
                &mut c.cur[x * stride..][..stride],
            ];
            let sums = if ADD {
                &mut sums[x * nd..][..nd]
            } else {
                &mut [][..]
            };
            let mins = if LEFT_TO_RIGHT {
                let [la, lb, lc, ll] = steps::<4, ADD, true>(
                    cost,
                    [pa, pb, pc, lr_prev],
                    [ma, mb, mc, lr_min],
                    self.penalties,
                    [oa, ob, oc, lr_cur],
                    sums,
                );
                lr_min = ll;
                std::mem::swap(lr_prev, lr_cur);
                [la, lb, lc]
            } else {
                steps::<3, ADD, false>(
                    cost,
                    [pa, pb, pc],
                    [ma, mb, mc],
                    self.penalties,
                    [oa, ob, oc],
                    sums,
                )
            };
            [a.cur_min[x], b.cur_min[x], c.cur_min[x]] = mins;
        }
        for pair in &mut self.rows {
            std::mem::swap(&mut pair.prev, &mut pair.cur);
            std::mem::swap(&mut pair.prev_min, &mut pair.cur_min);
        }
        self.fresh = false;
    }

    /// Runs the right-to-left path of one row of `cost`, adding it into
    /// `sums`.
    #[inline(always)]
    fn right_to_left(&mut self, cost: &[u8], sums: &mut [i16]) {
        let nd = self.num_disp;
        let [a, b] = &mut self.scratch;
        a.copy_from_slice(&self.start);
        let mut prev_min = 0;
        for x in (0..self.width).rev() {
            [prev_min] = steps::<1, true, false>(
                &cost[x * nd..][..nd],
                [a],
                [prev_min],
                self.penalties,
                [b],
                &mut sums[x * nd..][..nd],
            );
            std::mem::swap(a, b);
        }
    }
}

/// One step of `N` paths' recurrences at one pixel for all disparities, in
/// one loop over the disparities (the pixel's costs read once): each
/// `prev[k]` and `out[k]` hold `D + 2` values (padding at both ends),
/// `cost` and `sum` hold `D`. When `ADD`, the new path costs are summed into
/// `sum`: written when `WRITE` (the first pass over a row), else added.
/// Returns each path's minimum.
#[inline(always)]
fn steps<const N: usize, const ADD: bool, const WRITE: bool>(
    cost: &[u8],
    prev: [&[i16]; N],
    prev_min: [i16; N],
    (p1, p2): (i16, i16),
    out: [&mut [i16]; N],
    sum: &mut [i16],
) -> [i16; N] {
    let n = cost.len();
    let lower = prev.map(|p| &p[..n]);
    let same = prev.map(|p| &p[1..n + 1]);
    let upper = prev.map(|p| &p[2..n + 2]);
    let out = out.map(|o| &mut o[1..n + 1]);
    let jump = prev_min.map(|m| m + p2);
    let mut best = [i16::MAX; N];
    let sum = if ADD { &mut sum[..n] } else { sum };
    for d in 0..n {
        let c = i16::from(cost[d]);
        let mut total = 0i16;
        for k in 0..N {
            let m = same[k][d]
                .min(lower[k][d].min(upper[k][d]) + p1)
                .min(jump[k]);
            let v = c + m - prev_min[k];
            out[k][d] = v;
            best[k] = best[k].min(v);
            total += v;
        }
        if ADD {
            if WRITE {
                sum[d] = total;
            } else {
                sum[d] += total;
            }
        }
    }
    best
}
