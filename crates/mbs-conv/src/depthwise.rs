//! Convolutions with one input channel per group (depthwise, and their
//! channel multipliers) as direct loops over each channel's plane: as
//! products they would have a single row.

use rayon::prelude::*;

use crate::unfold::valid;
use crate::{Conv, planes_mut};

/// Calls `visit(output offset, input offset, run)` for each tap's run of
/// output positions along the width whose input lies inside the input,
/// for one tap: `run` output positions from the output offset, inputs
/// `stride` apart from the input offset.
fn runs(conv: &Conv, tap: usize, mut visit: impl FnMut(usize, usize, usize)) {
    let [out_d, out_h, out_w] = conv.output();
    let [in_d, in_h, in_w] = conv.input;
    let [_, kernel_h, kernel_w] = conv.kernel;
    let position = [
        tap / (kernel_h * kernel_w),
        tap / kernel_w % kernel_h,
        tap % kernel_w,
    ];
    let offset: [isize; 3] = std::array::from_fn(|axis| {
        (position[axis] * conv.dilation[axis]) as isize - conv.padding[axis][0] as isize
    });
    let depths = valid(out_d, conv.stride[0], offset[0], in_d);
    let heights = valid(out_h, conv.stride[1], offset[1], in_h);
    let widths = valid(out_w, conv.stride[2], offset[2], in_w);
    if widths.is_empty() {
        return;
    }
    for od in depths {
        let id = ((od * conv.stride[0]) as isize + offset[0]) as usize;
        for oh in heights.clone() {
            let ih = ((oh * conv.stride[1]) as isize + offset[1]) as usize;
            let iw = ((widths.start * conv.stride[2]) as isize + offset[2]) as usize;
            visit(
                (od * out_h + oh) * out_w + widths.start,
                (id * in_h + ih) * in_w + iw,
                widths.len(),
            );
        }
    }
}

/// The dot product of two slices of one length, in 8 lanes (a sum in
/// one register could not be vectorised: float addition does not
/// reassociate).
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut lanes = [0.0f32; 8];
    let (a_chunks, b_chunks) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = a_chunks
        .remainder()
        .iter()
        .zip(b_chunks.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (a, b) in a_chunks.zip(b_chunks) {
        for lane in 0..8 {
            lanes[lane] += a[lane] * b[lane];
        }
    }
    lanes.iter().sum::<f32>() + tail
}

/// The dot product of `a` with every `stride`-th value of `b`: the
/// strided values gathered 64 at a time, then [`dot`].
fn dot_strided(a: &[f32], b: &[f32], stride: usize) -> f32 {
    let mut gathered = [0.0f32; 64];
    let mut strided = b.iter().step_by(stride);
    a.chunks(64)
        .map(|a| {
            let chunk = &mut gathered[..a.len()];
            chunk
                .iter_mut()
                .zip(&mut strided)
                .for_each(|(g, b)| *g = *b);
            dot(a, chunk)
        })
        .sum()
}

/// Output channels per input channel.
fn multiplier(conv: &Conv) -> usize {
    conv.out_channels / conv.in_channels
}

pub fn forward(conv: &Conv, input: &[f32], weight: &[f32], output: &mut [f32]) {
    let (taps, in_plane, out_plane) = (conv.taps(), conv.input_plane(), conv.output_plane());
    let stride = conv.stride[2];
    // Strided 2-D kernels sum in registers; with stride 1 adding tap by
    // tap along contiguous rows is as fast (0.8 ms against 1.0-1.8 for
    // IGEV-Stereo's 96-channel layer; stride 2: 0.95 against 0.65-0.73).
    let in_registers =
        stride > 1 && conv.kernel[0] == 1 && conv.input[0] == 1 && conv.dilation == [1, 1, 1];
    planes_mut(output, out_plane)
        .enumerate()
        .for_each(|(index, y)| {
            let (item, out_channel) = (index / conv.out_channels, index % conv.out_channels);
            let channel = out_channel / multiplier(conv);
            let x = &input[(item * conv.in_channels + channel) * in_plane..][..in_plane];
            let w = &weight[out_channel * taps..][..taps];
            if in_registers {
                return forward_plane(conv, x, w, y);
            }
            for (tap, &w) in w.iter().enumerate() {
                runs(conv, tap, |o, i, run| {
                    let y = &mut y[o..o + run];
                    match stride {
                        1 => y
                            .iter_mut()
                            .zip(&x[i..i + run])
                            .for_each(|(y, x)| *y += w * x),
                        _ => y
                            .iter_mut()
                            .zip(x[i..].iter().step_by(stride))
                            .for_each(|(y, x)| *y += w * x),
                    }
                });
            }
        });
}

/// Output positions summed together in registers by [`forward_plane`].
const LANES: usize = 8;

/// One channel's plane of a strided 2-D undilated depthwise convolution, every
/// output the sum of all its taps kept in registers, [`LANES`] outputs
/// along the width at a time (adding tap by tap into the output would load
/// and store it once per multiply-add). The input is first copied, zero
/// padded, into one plane per phase of the width stride (`phases[p][r][c]`
/// = padded `[r][c * stride + p]`), so that every tap reads its inputs
/// contiguously.
fn forward_plane(conv: &Conv, x: &[f32], w: &[f32], y: &mut [f32]) {
    let out_w = conv.output()[2];
    let [_, in_h, in_w] = conv.input;
    let [_, kernel_h, kernel_w] = conv.kernel;
    let [_, stride_h, stride] = conv.stride;
    let [_, [top, bottom], [left, right]] = conv.padding;
    let rows = in_h + top + bottom;
    let phase_w = (in_w + left + right).div_ceil(stride);
    let mut phases = vec![0.0f32; stride * rows * phase_w];
    for phase in 0..stride {
        // The first input column whose padded column lies in this phase.
        let first = (phase + stride - left % stride) % stride;
        let column = (first + left) / stride;
        for (r, x_row) in x.chunks(in_w).enumerate() {
            let at = (phase * rows + r + top) * phase_w + column;
            let values = x_row.iter().skip(first).step_by(stride);
            phases[at..]
                .iter_mut()
                .zip(values)
                .for_each(|(p, &x)| *p = x);
        }
    }
    let full = out_w / LANES * LANES;
    // Each tap's first input for output row 0; row `oh` starts
    // `oh * stride_h` padded rows further.
    let taps: Vec<(usize, f32)> = (0..kernel_h)
        .flat_map(|ky| (0..kernel_w).map(move |kx| (ky, kx)))
        .map(|(ky, kx)| {
            let at = (kx % stride * rows + ky) * phase_w + kx / stride;
            (at, w[ky * kernel_w + kx])
        })
        .collect();
    for (oh, y_row) in y.chunks_mut(out_w).enumerate() {
        let phases = &phases[oh * stride_h * phase_w..];
        for start in (0..full).step_by(LANES) {
            let mut sums = [0.0f32; LANES];
            for &(row, w) in &taps {
                let xs = &phases[row + start..][..LANES];
                for lane in 0..LANES {
                    sums[lane] += w * xs[lane];
                }
            }
            y_row[start..start + LANES].copy_from_slice(&sums);
        }
        for (ow, y) in y_row.iter_mut().enumerate().skip(full) {
            *y = taps.iter().map(|&(row, w)| w * phases[row + ow]).sum();
        }
    }
}

pub fn input_gradient(conv: &Conv, weight: &[f32], output_gradient: &[f32], gradient: &mut [f32]) {
    let (taps, in_plane, out_plane) = (conv.taps(), conv.input_plane(), conv.output_plane());
    let stride = conv.stride[2];
    let multiplier = multiplier(conv);
    planes_mut(gradient, in_plane)
        .enumerate()
        .for_each(|(index, dx)| {
            let (item, channel) = (index / conv.in_channels, index % conv.in_channels);
            for out_channel in channel * multiplier..(channel + 1) * multiplier {
                let dy = &output_gradient[(item * conv.out_channels + out_channel) * out_plane..]
                    [..out_plane];
                let w = &weight[out_channel * taps..][..taps];
                for (tap, &w) in w.iter().enumerate() {
                    runs(conv, tap, |o, i, run| match stride {
                        1 => dx[i..i + run]
                            .iter_mut()
                            .zip(&dy[o..o + run])
                            .for_each(|(dx, dy)| *dx += w * dy),
                        _ => dx[i..]
                            .iter_mut()
                            .step_by(stride)
                            .zip(&dy[o..o + run])
                            .for_each(|(dx, dy)| *dx += w * dy),
                    });
                }
            }
        });
}

pub fn weight_gradient(conv: &Conv, input: &[f32], output_gradient: &[f32], gradient: &mut [f32]) {
    let (taps, in_plane, out_plane) = (conv.taps(), conv.input_plane(), conv.output_plane());
    let stride = conv.stride[2];
    let multiplier = multiplier(conv);
    gradient
        .par_chunks_mut(taps)
        .enumerate()
        .for_each(|(out_channel, dw)| {
            let channel = out_channel / multiplier;
            for item in 0..conv.batch {
                let x = &input[(item * conv.in_channels + channel) * in_plane..][..in_plane];
                let dy = &output_gradient[(item * conv.out_channels + out_channel) * out_plane..]
                    [..out_plane];
                for (tap, dw) in dw.iter_mut().enumerate() {
                    let mut sum = 0.0f32;
                    runs(conv, tap, |o, i, run| {
                        sum += match stride {
                            1 => dot(&dy[o..o + run], &x[i..i + run]),
                            _ => dot_strided(&dy[o..o + run], &x[i..], stride),
                        };
                    });
                    *dw += sum;
                }
            }
        });
}
