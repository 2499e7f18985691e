//! The unfolded input of a block of output rows (im2col) and its fold
//! back onto the input (col2im), for one item and group.

use rayon::prelude::*;

use crate::Conv;

/// The output positions `o` in `0..outputs` whose input position
/// `o * stride + offset` lies in `0..inputs`, as a range.
pub fn valid(
    outputs: usize,
    stride: usize,
    offset: isize,
    inputs: usize,
) -> std::ops::Range<usize> {
    let (stride_i, inputs_i) = (stride as isize, inputs as isize);
    // First o with o * stride + offset >= 0, last with < inputs.
    let low = if offset >= 0 {
        0
    } else {
        (-offset + stride_i - 1) / stride_i
    };
    let high = if inputs_i - offset <= 0 {
        0
    } else {
        (inputs_i - offset - 1) / stride_i + 1
    };
    let low = (low as usize).min(outputs);
    low..(high as usize).clamp(low, outputs)
}

/// The tap `(a, b, e)` of row `row % taps` and its input offsets along
/// depth, height and width (before the stride).
fn tap_offsets(conv: &Conv, tap: usize) -> [isize; 3] {
    let [_, kernel_h, kernel_w] = conv.kernel;
    let position = [
        tap / (kernel_h * kernel_w),
        tap / kernel_w % kernel_h,
        tap % kernel_w,
    ];
    std::array::from_fn(|axis| {
        (position[axis] * conv.dilation[axis]) as isize - conv.padding[axis][0] as isize
    })
}

/// Where, in a channel's plane, the input line starts that output row `q`
/// (flattened depth x height) reads for a tap of depth and height offsets
/// `offsets`; `None` when that line lies in the padding.
fn input_line(conv: &Conv, q: usize, offsets: [isize; 2]) -> Option<usize> {
    let [_, out_h, _] = conv.output();
    let [in_d, in_h, in_w] = conv.input;
    let id = ((q / out_h) * conv.stride[0]) as isize + offsets[0];
    let ih = ((q % out_h) * conv.stride[1]) as isize + offsets[1];
    let inside = (0..in_d as isize).contains(&id) && (0..in_h as isize).contains(&ih);
    inside.then(|| (id as usize * in_h + ih as usize) * in_w)
}

/// Writes into `unfolded` (`[C_in / groups * taps, count * W']`) the input
/// values `input` (one item's group of channels) each output position of
/// rows `first..first + count` (flattened depth x height) multiplies with
/// each weight.
pub fn unfold(conv: &Conv, input: &[f32], first: usize, count: usize, unfolded: &mut [f32]) {
    let [_, _, out_w] = conv.output();
    let [in_d, in_h, in_w] = conv.input;
    let (taps, plane) = (conv.taps(), in_d * in_h * in_w);
    let columns = count * out_w;
    unfolded
        .par_chunks_mut(columns)
        .enumerate()
        .for_each(|(row, values)| {
            let channel = &input[row / taps * plane..][..plane];
            let [offset_d, offset_h, offset_w] = tap_offsets(conv, row % taps);
            let span = valid(out_w, conv.stride[2], offset_w, in_w);
            for (slot, values) in values.chunks_mut(out_w).enumerate() {
                let Some(line) = input_line(conv, first + slot, [offset_d, offset_h]) else {
                    values.fill(0.0);
                    continue;
                };
                let line = &channel[line..][..in_w];
                values[..span.start].fill(0.0);
                values[span.end..].fill(0.0);
                let start = (span.start * conv.stride[2]) as isize + offset_w;
                match conv.stride[2] {
                    1 => {
                        values[span.clone()].copy_from_slice(&line[start as usize..][..span.len()])
                    }
                    stride => {
                        for (k, value) in values[span.clone()].iter_mut().enumerate() {
                            *value = line[start as usize + k * stride];
                        }
                    }
                }
            }
        });
}

/// Adds the unfolded gradient `unfolded` (laid out as [`unfold`]'s) of
/// rows `first..first + count` onto `input_gradient` (one item's group of
/// channels), each value onto the input position it was read from.
pub fn fold(conv: &Conv, unfolded: &[f32], first: usize, count: usize, input_gradient: &mut [f32]) {
    let [_, _, out_w] = conv.output();
    let [in_d, in_h, in_w] = conv.input;
    let (taps, plane) = (conv.taps(), in_d * in_h * in_w);
    let columns = count * out_w;
    // Each channel's taps write only that channel's plane.
    input_gradient
        .par_chunks_mut(plane)
        .enumerate()
        .for_each(|(channel, gradient)| {
            for tap in 0..taps {
                let row = channel * taps + tap;
                let values = &unfolded[row * columns..][..columns];
                let [offset_d, offset_h, offset_w] = tap_offsets(conv, tap);
                let span = valid(out_w, conv.stride[2], offset_w, in_w);
                for (slot, values) in values.chunks(out_w).enumerate() {
                    let Some(line) = input_line(conv, first + slot, [offset_d, offset_h]) else {
                        continue;
                    };
                    let line = &mut gradient[line..][..in_w];
                    let start = (span.start * conv.stride[2]) as isize + offset_w;
                    for (k, value) in values[span.clone()].iter().enumerate() {
                        line[start as usize + k * conv.stride[2]] += value;
                    }
                }
            }
        });
}
