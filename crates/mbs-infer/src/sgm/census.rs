//! Sparse census transform and the per-row census matching cost (Hamming
//! distance). Sampling every other pixel of the window (a checkerboard)
//! keeps the window's reach with half the bits: on Teddy and Tsukuba a
//! sparse 9x7 census (32 bits) matches as well as the dense one (62 bits),
//! and 32-bit signatures halve the cost of the Hamming distances.

use rayon::prelude::*;

/// The window offsets `(dy, dx)` a census samples: the cells of a
/// `win_w` x `win_h` window whose `dx + dy` is even (corners included),
/// centre excluded, in row-major order.
pub fn samples(win_w: usize, win_h: usize) -> Vec<(usize, usize)> {
    (0..win_h)
        .flat_map(|dy| (0..win_w).map(move |dx| (dy, dx)))
        .filter(|&(dy, dx)| (dy, dx) != (win_h / 2, win_w / 2) && (dx + dy) % 2 == 0)
        .collect()
}

/// Census signatures of a row-major luma image over the [`samples`] of a
/// `win_w` x `win_h` window (odd sides, at most 32 samples): one bit per
/// sample, set where it is darker than the centre. Byte `g` of a signature
/// holds samples `8g..8g+8`, the first in the most significant bit.
/// Borders replicate the edge pixels.
pub fn census(gray: &[u8], width: usize, win_w: usize, win_h: usize) -> Vec<u32> {
    let height = gray.len() / width;
    let (rx, ry) = (win_w / 2, win_h / 2);
    let pw = width + 2 * rx;
    let mut padded = vec![0u8; pw * (height + 2 * ry)];
    for (py, row) in padded.chunks_exact_mut(pw).enumerate() {
        let y = py.saturating_sub(ry).min(height - 1);
        let src = &gray[y * width..][..width];
        for (px, v) in row.iter_mut().enumerate() {
            *v = src[px.saturating_sub(rx).min(width - 1)];
        }
    }
    let offsets = samples(win_w, win_h);
    let arch = pulp::Arch::new();
    let mut out = vec![0u32; width * height];
    out.par_chunks_mut(width)
        .enumerate()
        .for_each_init(Vec::new, |planes, (y, row)| {
            arch.dispatch(CensusRow {
                padded: &padded,
                offsets: &offsets,
                top_left: y * pw,
                pw,
                centre: ry * pw + rx,
                planes,
                row,
            });
        });
    out
}

/// The signatures of one row, run through [`pulp::Arch::dispatch`] so that
/// its byte loops are compiled for AVX2 where the processor has it (32
/// lanes instead of 16); the results are the same either way.
struct CensusRow<'a> {
    /// The edge-replicated image, `pw` pixels a row.
    padded: &'a [u8],
    /// The window offsets `(dy, dx)` sampled, eight to a signature byte.
    offsets: &'a [(usize, usize)],
    /// Where the row's window starts in `padded`.
    top_left: usize,
    /// The padded width.
    pw: usize,
    /// The centre's offset from the window's start.
    centre: usize,
    /// Scratch: one byte plane of the row per signature byte.
    planes: &'a mut Vec<u8>,
    /// The row's signatures.
    row: &'a mut [u32],
}

impl pulp::WithSimd for CensusRow<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let width = self.row.len();
        let centre = &self.padded[self.top_left + self.centre..][..width];
        // Eight comparisons per byte, in byte loops; byte `g` of a
        // signature holds offsets `8g..8g+8`.
        self.planes.clear();
        self.planes.resize(4 * width, 0);
        for (group, plane) in self
            .offsets
            .chunks(8)
            .zip(self.planes.chunks_exact_mut(width))
        {
            for &(dy, dx) in group {
                let neighbour = &self.padded[self.top_left + dy * self.pw + dx..][..width];
                for ((b, &n), &c) in plane.iter_mut().zip(neighbour).zip(centre) {
                    *b = (*b << 1) | u8::from(n < c);
                }
            }
        }
        let [p0, p1, p2, p3] = [0, 1, 2, 3].map(|g| &self.planes[g * width..][..width]);
        for (x, o) in self.row.iter_mut().enumerate() {
            *o = u32::from_le_bytes([p0[x], p1[x], p2[x], p3[x]]);
        }
    }
}

/// The right-view signatures as byte planes, each row reversed:
/// `planes[(y * 4 + g) * width + k]` is byte `g` of the signature at column
/// `width - 1 - k`, so that the signatures at `x - d` for `d = 0, 1, …` lie
/// contiguously, one byte plane at a time (see [`cost_row`]).
pub fn reversed_planes(signatures: &[u32], width: usize) -> Vec<u8> {
    let mut planes = vec![0u8; signatures.len() * 4];
    for (row, out) in signatures
        .chunks_exact(width)
        .zip(planes.chunks_exact_mut(4 * width))
    {
        for (k, s) in row.iter().rev().enumerate() {
            for (g, b) in s.to_le_bytes().into_iter().enumerate() {
                out[g * width + k] = b;
            }
        }
    }
    planes
}

/// Matching costs of one row, `out[x * D + d]` = Hamming distance between
/// the left signature at `x` and the right one at `x - d`, for `D =
/// out.len() / left.len()` disparities; `right_planes` is the row's
/// [`reversed_planes`]. Disparities past the left border (`d > x`) cost
/// `invalid`. Inlined into its caller, so that it is compiled with the
/// caller's target features.
#[inline(always)]
pub fn cost_row(left: &[u32], right_planes: &[u8], invalid: u8, out: &mut [u8]) {
    let width = left.len();
    let num_disp = out.len() / width;
    for (x, (&l, costs)) in left.iter().zip(out.chunks_exact_mut(num_disp)).enumerate() {
        let n = num_disp.min(x + 1);
        let start = width - 1 - x;
        let (matched, beyond) = costs.split_at_mut(n);
        let [first, rest @ ..] = l.to_le_bytes();
        // A byte's bit count vectorises at every x86-64 level: a nibble
        // table lookup with AVX2 (and SSSE3), shifts and adds on the
        // baseline; counting per byte also spares the packing of 32-bit
        // counts into bytes. The first byte's counts are stored, the
        // others' added.
        let right = &right_planes[start..][..n];
        for (c, &rb) in matched.iter_mut().zip(right) {
            *c = (first ^ rb).count_ones() as u8;
        }
        for (g, lb) in rest.into_iter().enumerate() {
            let right = &right_planes[(g + 1) * width + start..][..n];
            for (c, &rb) in matched.iter_mut().zip(right) {
                *c += (lb ^ rb).count_ones() as u8;
            }
        }
        beyond.fill(invalid);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn census_bits_follow_the_neighbours() {
        // 3x3 image, 3x3 window: centre 5; the samples are the corners.
        let gray = [1, 9, 9, 9, 5, 1, 9, 9, 1];
        assert_eq!(samples(3, 3), vec![(0, 0), (0, 2), (2, 0), (2, 2)]);
        let c = census(&gray, 3, 3, 3);
        // Corners (1, 9, 9, 1): darker than 5 at samples 0 and 3.
        assert_eq!(c[4], 0b1001);
        assert_eq!(samples(9, 7).len(), 32);
    }

    #[test]
    fn cost_row_matches_shifted_signatures() {
        let left = [0b0u32, 0b1, 0b11, 0b111];
        let right = [0b1u32, 0b11, 0b111, 0b1111];
        let planes = reversed_planes(&right, 4);
        let mut out = vec![0u8; 8];
        cost_row(&left, &planes, 99, &mut out);
        // x = 0: d = 0 -> |0 ^ 1| = 1; d = 1 is past the border.
        assert_eq!(&out[..2], &[1, 99]);
        // x = 3: d = 0 -> 0b111 ^ 0b1111 = 1 bit; d = 1 -> 0b111 ^ 0b111 = 0.
        assert_eq!(&out[6..], &[1, 0]);
        // Bytes beyond the first count too.
        let left = [0xFF00_FF00u32, 0];
        let planes = reversed_planes(&[0x00FF_00FFu32, 0x0F00_0001], 2);
        let mut out = vec![0u8; 4];
        cost_row(&left, &planes, 99, &mut out);
        // x = 1: d = 0 -> 0x0F00_0001 has 5 bits; d = 1 -> 0x00FF_00FF has 16.
        assert_eq!(out, vec![32, 99, 5, 16]);
    }
}
