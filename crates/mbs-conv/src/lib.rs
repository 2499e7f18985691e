//! Convolutions on the CPU on f32 slices, forward, input gradient and weight gradient, for any stride, padding, dilation and groups: unfolded input times weights through gemm, depthwise ones as direct loops.
//!
//! Tensors are contiguous in PyTorch's (and burn's) layout: input
//! `[N, C_in, D, H, W]`, weights `[C_out, C_in / groups, kD, kH, kW]`,
//! output `[N, C_out, D', H', W']`; a 2-D convolution is a 3-D one of
//! depth one. With `K = C_in / groups * kD * kH * kW` and `P = D' H' W'`,
//! per item and group:
//!
//! ```text
//! forward          Y[C_out/g, P]  = W[C_out/g, K] x U[K, P]          U: the unfolded input (im2col)
//! weight gradient  dW[C_out/g, K] += dY[C_out/g, P] x U[K, P]^T      summed over the items
//! input gradient   dU[K, P]       = W[C_out/g, K]^T x dY[C_out/g, P], folded back (col2im)
//! ```
//!
//! `U` is built a block of output rows at a time (at most
//! [`PART_BUDGET`] values), the blocks shared among parts that run side
//! by side, each with its own buffer, its products on one thread (a fold
//! takes larger blocks, [`FOLD_BUDGET`], one after the other); a 1x1
//! convolution of stride 1 without padding uses the input itself. The
//! input gradient of a stride-1 convolution is the forward pass of its
//! transpose (flipped kernel, full padding) rather than a fold.
//! Convolutions with one input channel per group (depthwise) run as direct
//! loops over each channel's plane instead of products with one row.

mod depthwise;
mod matmul;
mod unfold;

use rayon::prelude::*;

use matmul::{Matrix, matmul};
use unfold::{fold, unfold};

/// The most parts the blocks of a weight gradient are shared among (run
/// side by side on rayon's threads). Fixed, not the thread count: the
/// parts' sums are added in order, and the gradient must not depend on
/// the machine. A forward pass uses one part per thread (each output is
/// one product, whatever the parts).
const PARTS: usize = 8;

/// Multiply-adds below which a forward pass or weight gradient is not
/// split further.
const PART_WORK: usize = 1 << 22;

/// The most values the unfolded input of one block holds where blocks run
/// side by side, one product per thread (forward passes, weight gradients,
/// stride-1 input gradients): 1 MB of f32, which stays in a core's L2
/// cache between the unfolding and the product, and leaves enough blocks
/// to share evenly on small maps (2^16 to 2^21 measured on the networks'
/// layers: 2^18 was fastest, 3x3 128->128 at 48x64 15-20 % faster than
/// with 2^20, no layer slower).
pub const PART_BUDGET: usize = 1 << 18;

/// The most values the unfolded input gradient of one block holds where
/// blocks are folded one after the other, each product spread across the
/// threads (input gradients of strided convolutions): 4 MB of f32; the
/// 7x7 stride-2 stem's input gradient takes 9.5 ms with it, 12 ms with
/// 2^18, 20 ms with 2^16.
pub const FOLD_BUDGET: usize = 1 << 20;

/// The geometry of one convolution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Conv {
    /// Items in the batch.
    pub batch: usize,
    /// Input channels (all groups).
    pub in_channels: usize,
    /// Output channels (all groups).
    pub out_channels: usize,
    /// Groups; both channel counts are multiples of it.
    pub groups: usize,
    /// Input depth, height and width (depth 1 for 2-D).
    pub input: [usize; 3],
    /// Kernel depth, height and width.
    pub kernel: [usize; 3],
    /// Strides along depth, height and width.
    pub stride: [usize; 3],
    /// Zero padding before and after, along depth, height and width.
    pub padding: [[usize; 2]; 3],
    /// Dilations along depth, height and width.
    pub dilation: [usize; 3],
}

impl Conv {
    /// Output depth, height and width.
    pub fn output(&self) -> [usize; 3] {
        std::array::from_fn(|axis| {
            let padded = self.input[axis] + self.padding[axis][0] + self.padding[axis][1];
            let reach = self.dilation[axis] * (self.kernel[axis] - 1) + 1;
            if padded < reach {
                0
            } else {
                (padded - reach) / self.stride[axis] + 1
            }
        })
    }

    /// Why the geometry is not a convolution this crate computes, if it is not.
    pub fn check(&self) -> Result<(), String> {
        let positive = [self.batch, self.in_channels, self.out_channels, self.groups];
        if positive.contains(&0)
            || self.kernel.contains(&0)
            || self.stride.contains(&0)
            || self.dilation.contains(&0)
        {
            return Err(format!("a size, stride or dilation of 0 in {self:?}"));
        }
        if !self.in_channels.is_multiple_of(self.groups)
            || !self.out_channels.is_multiple_of(self.groups)
        {
            return Err(format!(
                "{} input and {} output channels do not split into {} groups",
                self.in_channels, self.out_channels, self.groups
            ));
        }
        if self.output().contains(&0) {
            return Err(format!(
                "the kernel does not fit the padded input in {self:?}"
            ));
        }
        Ok(())
    }

    /// Input values per item and channel.
    fn input_plane(&self) -> usize {
        self.input.iter().product()
    }

    /// Output values per item and channel.
    fn output_plane(&self) -> usize {
        self.output().iter().product()
    }

    /// Kernel taps per input channel.
    fn taps(&self) -> usize {
        self.kernel.iter().product()
    }

    fn in_per_group(&self) -> usize {
        self.in_channels / self.groups
    }

    fn out_per_group(&self) -> usize {
        self.out_channels / self.groups
    }

    /// Rows of the unfolded input of one group: `C_in / groups * taps`.
    fn unfolded_rows(&self) -> usize {
        self.in_per_group() * self.taps()
    }

    /// Lengths of the input, weight and output slices.
    pub fn lengths(&self) -> [usize; 3] {
        [
            self.batch * self.in_channels * self.input_plane(),
            self.out_channels * self.unfolded_rows(),
            self.batch * self.out_channels * self.output_plane(),
        ]
    }

    /// Whether the unfolded input is the input itself: 1x1 kernel, stride
    /// 1, no padding.
    fn is_pointwise(&self) -> bool {
        self.kernel == [1, 1, 1] && self.stride == [1, 1, 1] && self.padding == [[0, 0]; 3]
    }

    /// One input channel per group: direct loops ([`depthwise`]).
    fn is_depthwise(&self) -> bool {
        self.in_per_group() == 1 && self.groups > 1
    }

    /// Output rows (of the flattened depth x height) per unfolded block
    /// of at most `budget` values.
    fn block_rows(&self, budget: usize) -> usize {
        let [depth, height, width] = self.output();
        let per_row = self.unfolded_rows() * width;
        (budget / per_row.max(1)).clamp(1, depth * height)
    }

    /// The blocks of output rows: (first row, rows).
    fn blocks(&self, budget: usize) -> impl Iterator<Item = (usize, usize)> {
        let [depth, height, _] = self.output();
        let rows = depth * height;
        let step = self.block_rows(budget);
        (0..rows)
            .step_by(step)
            .map(move |first| (first, step.min(rows - first)))
    }

    fn assert_lengths(&self, input: usize, weight: usize, output: usize) {
        if let Err(reason) = self.check() {
            panic!("mbs-conv: {reason}");
        }
        assert_eq!(
            [input, weight, output],
            self.lengths(),
            "mbs-conv: slice lengths (input, weight, output) for {self:?}"
        );
    }

    /// The convolution of `input` with `weight` (no bias).
    pub fn forward(&self, input: &[f32], weight: &[f32]) -> Vec<f32> {
        self.forward_within(input, weight, PART_BUDGET)
    }

    /// [`Self::forward`] unfolding at most `budget` values at a time.
    fn forward_within(&self, input: &[f32], weight: &[f32], budget: usize) -> Vec<f32> {
        let mut output = vec![0.0; self.lengths()[2]];
        self.assert_lengths(input.len(), weight.len(), output.len());
        if self.is_depthwise() {
            depthwise::forward(self, input, weight, &mut output);
            return output;
        }
        if self.is_pointwise() {
            self.forward_pointwise(input, weight, &mut output);
            return output;
        }
        let (rows, plane) = (self.unfolded_rows(), self.output_plane());
        let width = self.output()[2];
        let block_rows = self.block_rows(budget);
        let cout = self.out_per_group();
        // The blocks of every item and group, shared among parts as the
        // weight gradient's (products of few rows run faster side by side
        // than each split across threads). Each block's output is one
        // piece of each of its group's channel planes: the pieces are
        // handed to the blocks up front, and each part writes a block's
        // product into a buffer the size of one block, then into them.
        let units: Vec<(usize, usize, usize, usize)> = (0..self.batch)
            .flat_map(|item| (0..self.groups).map(move |group| (item, group)))
            .flat_map(|(item, group)| {
                self.blocks(budget)
                    .map(move |(first, count)| (item, group, first, count))
            })
            .collect();
        let mut pieces = self.block_pieces(&mut output, units.len(), budget);
        let work = self.batch * plane * rows * self.out_channels;
        let parts = parts(units.len(), rayon::current_num_threads(), work);
        let per_part = units.len().div_ceil(parts);
        units
            .par_chunks(per_part)
            .zip(pieces.par_chunks_mut(per_part))
            .for_each(|(units, pieces)| {
                let mut product = vec![0.0; cout * block_rows * width];
                let mut unfolded = vec![0.0; rows * block_rows * width];
                for (&(item, group, first, count), pieces) in units.iter().zip(pieces) {
                    let x = self.group_input(input, item, group);
                    let w = Matrix::rows(&weight[self.group_weight(group)], rows);
                    let columns = count * width;
                    let u = &mut unfolded[..rows * columns];
                    unfold(self, x, first, count, u);
                    let y = &mut product[..cout * columns];
                    matmul(y, columns, w, Matrix::rows(u, columns), false, parts == 1);
                    for (piece, values) in pieces.iter_mut().zip(y.chunks(columns)) {
                        piece.copy_from_slice(values);
                    }
                }
            });
        output
    }

    /// The forward pass of a pointwise convolution into `output`: one
    /// product per item and group, the input as it is, split across
    /// threads by gemm.
    fn forward_pointwise(&self, input: &[f32], weight: &[f32], output: &mut [f32]) {
        let (rows, plane) = (self.unfolded_rows(), self.output_plane());
        for item in 0..self.batch {
            for group in 0..self.groups {
                let x = Matrix::rows(self.group_input(input, item, group), plane);
                let w = Matrix::rows(&weight[self.group_weight(group)], rows);
                let y = &mut output[self.group_output(item, group)];
                matmul(y, plane, w, x, false, true);
            }
        }
    }

    /// `output` cut into the pieces each of `units` blocks (of `budget`
    /// values, every item and group in turn) writes: per block, one piece
    /// of each of its group's channel planes.
    fn block_pieces<'o>(
        &self,
        output: &'o mut [f32],
        units: usize,
        budget: usize,
    ) -> Vec<Vec<&'o mut [f32]>> {
        let (plane, width, cout) = (self.output_plane(), self.output()[2], self.out_per_group());
        let mut pieces: Vec<Vec<&mut [f32]>> = (0..units).map(|_| Vec::new()).collect();
        let blocks_per_group = self.blocks(budget).count();
        for (row, mut plane_values) in output.chunks_mut(plane).enumerate() {
            // Channel planes run item by item, channel by channel, so a
            // group's blocks are consecutive units.
            let first_unit = row / cout * blocks_per_group;
            for (unit, (_, count)) in self.blocks(budget).enumerate() {
                let (piece, rest) = plane_values.split_at_mut(count * width);
                pieces[first_unit + unit].push(piece);
                plane_values = rest;
            }
        }
        pieces
    }

    /// The gradient of a loss with respect to the weights, given the
    /// input and the gradient with respect to the output.
    pub fn weight_gradient(&self, input: &[f32], output_gradient: &[f32]) -> Vec<f32> {
        self.weight_gradient_within(input, output_gradient, PART_BUDGET)
    }

    /// [`Self::weight_gradient`] unfolding at most `budget` values at a time.
    fn weight_gradient_within(
        &self,
        input: &[f32],
        output_gradient: &[f32],
        budget: usize,
    ) -> Vec<f32> {
        let mut gradient = vec![0.0; self.lengths()[1]];
        self.assert_lengths(input.len(), gradient.len(), output_gradient.len());
        if self.is_depthwise() {
            depthwise::weight_gradient(self, input, output_gradient, &mut gradient);
            return gradient;
        }
        let (rows, plane) = (self.unfolded_rows(), self.output_plane());
        let block_rows = self.block_rows(budget);
        // The items' blocks of output rows, shared among at most PARTS
        // parts, each summing its products into a gradient of its own:
        // parallel over the output positions, which a product of few rows
        // and columns (out channels x kernel) cannot be inside, and summed
        // in a fixed order, so the result does not depend on the threads.
        let units: Vec<(usize, usize, usize)> = (0..self.batch)
            .flat_map(|item| {
                self.blocks(budget)
                    .map(move |(first, count)| (item, first, count))
            })
            .collect();
        let work = self.batch * plane * rows * self.out_per_group();
        let parts = parts(units.len(), PARTS, work);
        let per_part = units.len().div_ceil(parts);
        for group in 0..self.groups {
            let partials: Vec<Vec<f32>> = units
                .par_chunks(per_part)
                .map(|units| {
                    let sources = (input, output_gradient);
                    self.partial_weight_gradient(sources, group, units, block_rows, parts == 1)
                })
                .collect();
            let dw = &mut gradient[self.group_weight(group)];
            for partial in partials {
                dw.iter_mut()
                    .zip(partial)
                    .for_each(|(sum, value)| *sum += value);
            }
        }
        gradient
    }

    /// One part's sum of `group`'s weight gradient over its `units` (item,
    /// first output row, rows) of the input and output gradient in
    /// `sources`, unfolding at most `block_rows` output rows at a time;
    /// gemm splits each product across threads when `parallel`.
    fn partial_weight_gradient(
        &self,
        (input, output_gradient): (&[f32], &[f32]),
        group: usize,
        units: &[(usize, usize, usize)],
        block_rows: usize,
        parallel: bool,
    ) -> Vec<f32> {
        let (rows, plane) = (self.unfolded_rows(), self.output_plane());
        let width = self.output()[2];
        let mut dw = vec![0.0; self.out_per_group() * rows];
        let mut unfolded = match self.is_pointwise() {
            true => Vec::new(),
            false => vec![0.0; rows * block_rows * width],
        };
        for (index, &(item, first, count)) in units.iter().enumerate() {
            let x = self.group_input(input, item, group);
            let dy = &output_gradient[self.group_output(item, group)];
            let (at, columns) = (first * width, count * width);
            let u = match self.is_pointwise() {
                true => Matrix::strided(&x[at..], rows, columns, plane),
                false => {
                    let u = &mut unfolded[..rows * columns];
                    unfold(self, x, first, count, u);
                    Matrix::rows(u, columns)
                }
            };
            let dy = Matrix::strided(&dy[at..], self.out_per_group(), columns, plane);
            matmul(&mut dw, rows, dy, u.transposed(), index > 0, parallel);
        }
        dw
    }

    /// The gradient of a loss with respect to the input, given the weights
    /// and the gradient with respect to the output.
    pub fn input_gradient(&self, weight: &[f32], output_gradient: &[f32]) -> Vec<f32> {
        self.input_gradient_within(weight, output_gradient, [PART_BUDGET, FOLD_BUDGET])
    }

    /// [`Self::input_gradient`] unfolding at most `part_budget` values at a
    /// time as a transposed forward pass, `fold_budget` as a fold.
    fn input_gradient_within(
        &self,
        weight: &[f32],
        output_gradient: &[f32],
        [part_budget, fold_budget]: [usize; 2],
    ) -> Vec<f32> {
        let mut gradient = vec![0.0; self.lengths()[0]];
        self.assert_lengths(gradient.len(), weight.len(), output_gradient.len());
        if self.is_depthwise() {
            depthwise::input_gradient(self, weight, output_gradient, &mut gradient);
            return gradient;
        }
        if let Some((transposed, flipped)) = self.transposed(weight) {
            return transposed.forward_within(output_gradient, &flipped, part_budget);
        }
        let (rows, plane) = (self.unfolded_rows(), self.output_plane());
        let width = self.output()[2];
        let mut unfolded = vec![0.0; rows * self.block_rows(fold_budget) * width];
        for item in 0..self.batch {
            for group in 0..self.groups {
                let w = Matrix::rows(&weight[self.group_weight(group)], rows).transposed();
                let dy = &output_gradient[self.group_output(item, group)];
                let range = self.group_input_range(item, group);
                let dx = &mut gradient[range];
                if self.is_pointwise() {
                    matmul(dx, plane, w, Matrix::rows(dy, plane), false, true);
                    continue;
                }
                for (first, count) in self.blocks(fold_budget) {
                    let columns = count * width;
                    let du = &mut unfolded[..rows * columns];
                    let at = first * width;
                    let dy = Matrix::strided(&dy[at..], self.out_per_group(), columns, plane);
                    matmul(du, columns, w, dy, false, true);
                    fold(self, du, first, count, dx);
                }
            }
        }
        gradient
    }

    /// For a convolution of stride 1 (not pointwise), the convolution
    /// whose forward pass is this one's input gradient, with its weights
    /// made from `weight`: channels in and out swapped within each group,
    /// the kernel flipped, each side padded by the kernel's reach less the
    /// original padding (a "full" convolution). `None` for other strides,
    /// or padding beyond the kernel's reach, where the gradient is folded.
    fn transposed(&self, weight: &[f32]) -> Option<(Conv, Vec<f32>)> {
        if self.stride != [1, 1, 1] || self.is_pointwise() {
            return None;
        }
        let reach: [usize; 3] = std::array::from_fn(|a| self.dilation[a] * (self.kernel[a] - 1));
        if (0..3).any(|a| self.padding[a].iter().any(|&p| p > reach[a])) {
            return None;
        }
        let [d, h, w] = self.output();
        let transposed = Conv {
            in_channels: self.out_channels,
            out_channels: self.in_channels,
            input: [d, h, w],
            padding: std::array::from_fn(|a| {
                [reach[a] - self.padding[a][0], reach[a] - self.padding[a][1]]
            }),
            ..*self
        };
        let (taps, cin, cout) = (self.taps(), self.in_per_group(), self.out_per_group());
        let mut flipped = vec![0.0; weight.len()];
        for group in 0..self.groups {
            for o in 0..cout {
                for i in 0..cin {
                    let from = ((group * cout + o) * cin + i) * taps;
                    let to = ((group * cin + i) * cout + o) * taps;
                    for tap in 0..taps {
                        flipped[to + taps - 1 - tap] = weight[from + tap];
                    }
                }
            }
        }
        Some((transposed, flipped))
    }

    fn group_input_range(&self, item: usize, group: usize) -> std::ops::Range<usize> {
        let size = self.in_per_group() * self.input_plane();
        let start = (item * self.groups + group) * size;
        start..start + size
    }

    fn group_input<'a>(&self, input: &'a [f32], item: usize, group: usize) -> &'a [f32] {
        &input[self.group_input_range(item, group)]
    }

    fn group_weight(&self, group: usize) -> std::ops::Range<usize> {
        let size = self.out_per_group() * self.unfolded_rows();
        group * size..(group + 1) * size
    }

    fn group_output(&self, item: usize, group: usize) -> std::ops::Range<usize> {
        let size = self.out_per_group() * self.output_plane();
        let start = (item * self.groups + group) * size;
        start..start + size
    }
}

/// How many parts `units` blocks of `work` multiply-adds in all are shared
/// among: at least one, at most `most` and at most one per [`PART_WORK`]
/// multiply-adds.
fn parts(units: usize, most: usize, work: usize) -> usize {
    units.min(most).min(work.div_ceil(PART_WORK)).max(1)
}

/// Splits `values` into consecutive planes of `plane` values, in parallel.
fn planes_mut(values: &mut [f32], plane: usize) -> rayon::slice::ChunksMut<'_, f32> {
    values.par_chunks_mut(plane.max(1))
}

#[cfg(test)]
mod tests;
