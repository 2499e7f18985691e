//! RAFT-Stereo's 1-D correlation pyramid (the official `CorrBlock1D`): the
//! dot products of every left feature with every right feature of the same
//! row, divided by `sqrt(channels)`, average-pooled by 2 along the right
//! image's width per level, and looked up at `2 radius + 1` points around
//! the current match with linear interpolation (zero outside the row).

use burn::tensor::{FloatDType, Tensor};

use crate::layers::counting;

/// All-pairs correlation rows and their pooled copies.
pub struct CorrelationPyramid {
    /// Per level: `[B * H * W1, W2 / 2^level]`.
    levels: Vec<Tensor<2>>,
    radius: usize,
    shape: [usize; 3],
}

impl CorrelationPyramid {
    /// The pyramid of `levels` levels of the features `[B, D, H, W]`.
    pub fn new(left: Tensor<4>, right: Tensor<4>, levels: usize, radius: usize) -> Self {
        let [batch, channels, height, width] = left.dims();
        let right_width = right.dims()[3];
        let volume = left
            .permute([0, 2, 3, 1])
            .matmul(right.permute([0, 2, 1, 3]))
            / (channels as f64).sqrt();
        let mut row = volume.reshape([batch * height * width, right_width]);
        let mut pyramid = Vec::with_capacity(levels);
        for _ in 1..levels {
            let pooled = halve_columns(row.clone());
            pyramid.push(row);
            row = pooled;
        }
        pyramid.push(row);
        CorrelationPyramid {
            levels: pyramid,
            radius,
            shape: [batch, height, width],
        }
    }

    /// Channels of a lookup: `levels * (2 radius + 1)`.
    pub fn channels(levels: usize, radius: usize) -> usize {
        levels * (2 * radius + 1)
    }

    /// The lookup `[B, levels * (2 radius + 1), H, W]` around the matching
    /// columns `x` (`[B, 1, H, W]`, right-image pixels; no gradient flows
    /// to them).
    pub fn lookup(&self, x: Tensor<4>) -> Tensor<4> {
        let [batch, height, width] = self.shape;
        let points = 2 * self.radius + 1;
        let offsets = lookup_offsets(self.radius, &x);
        let centres = x.detach().reshape([batch * height * width, 1]);
        let samples = self
            .levels
            .iter()
            .enumerate()
            .map(|(level, row)| {
                let positions = centres.clone() / 2f64.powi(level as i32) + offsets.clone();
                sample_linear(row, positions).reshape([batch, height, width, points])
            })
            .collect();
        Tensor::cat(samples, 3).permute([0, 3, 1, 2])
    }
}

/// The lookup offsets `[-radius, ..., radius]` as a `[1, 2 radius + 1]` row
/// on `like`'s device and in its format.
pub(crate) fn lookup_offsets(radius: usize, like: &Tensor<4>) -> Tensor<2> {
    let points = 2 * radius + 1;
    counting(points, like)
        .sub_scalar(radius as f64)
        .reshape([1, points])
}

/// `rows[n]` sampled at the fractional columns `positions[n, k]`, linearly
/// between the two neighbours, each counting zero outside the row (as
/// `grid_sample` with `align_corners=True` and zero padding).
pub(crate) fn sample_linear(rows: &Tensor<2>, positions: Tensor<2>) -> Tensor<2> {
    let width = rows.dims()[1] as f64;
    let left = positions.clone().floor();
    let weight = positions - left.clone();
    let tap = |column: Tensor<2>| {
        let inside = column
            .clone()
            .greater_equal_elem(0.0)
            .bool_and(column.clone().lower_equal_elem(width - 1.0))
            .cast(FloatDType::from(rows.dtype()));
        let index = column.clamp(0.0, width - 1.0).int();
        rows.clone().gather(1, index) * inside
    };
    let right = left.clone() + 1.0;
    tap(left) * (weight.clone().neg() + 1.0) + tap(right) * weight
}

/// Averages each pair of neighbouring columns of `row` `[R, C]` (the
/// official 1x2 average pooling, an odd last column dropped). A row of
/// one column is kept as it is: the official pooling refuses it (its
/// output would be empty), which happens only for images at most 32
/// pixels wide at 1/8 resolution.
fn halve_columns(row: Tensor<2>) -> Tensor<2> {
    let [rows, columns] = row.dims();
    if columns < 2 {
        return row;
    }
    row.narrow(1, 0, columns / 2 * 2)
        .reshape([rows, columns / 2, 2])
        .mean_dim(2)
        .reshape([rows, columns / 2])
}
