//! Upsampling of network outputs. Bilinear resizing is two matrix products
//! with fixed interpolation matrices, `U_h D U_w^T`: it has a backward pass
//! on every burn backend (burn's GPU `interpolate` has none) and runs as
//! fast on flex. Convex upsampling is RAFT's learned 3x3 combination.

use burn::tensor::activation::softmax;
use burn::tensor::ops::PadMode;
use burn::tensor::{Device, Tensor, TensorData};

/// The `[n_out, n_in]` matrix of 1-D linear interpolation with PyTorch's
/// `align_corners = false` convention (pixel centres at `i + 0.5`, source
/// coordinates clamped at the border).
pub fn interpolation_matrix(n_out: usize, n_in: usize) -> Vec<f32> {
    let scale = n_in as f64 / n_out as f64;
    linear_matrix(n_out, n_in, |i| ((i as f64 + 0.5) * scale - 0.5).max(0.0))
}

/// The `[n_out, n_in]` matrix that takes output `i` linearly from the
/// fractional input position `source(i)` (clamped to the last input).
fn linear_matrix(n_out: usize, n_in: usize, source: impl Fn(usize) -> f64) -> Vec<f32> {
    let mut matrix = vec![0.0f32; n_out * n_in];
    for i in 0..n_out {
        let source = source(i);
        let left = (source.floor() as usize).min(n_in - 1);
        let right = (left + 1).min(n_in - 1);
        let weight = (source - left as f64) as f32;
        matrix[i * n_in + left] += 1.0 - weight;
        matrix[i * n_in + right] += weight;
    }
    matrix
}

/// The `[n_out, n_in]` matrix of 1-D linear interpolation with PyTorch's
/// `align_corners = true` convention (the first and last samples of both
/// grids coincide).
pub fn aligned_interpolation_matrix(n_out: usize, n_in: usize) -> Vec<f32> {
    let scale = if n_out > 1 {
        (n_in - 1) as f64 / (n_out - 1) as f64
    } else {
        0.0
    };
    linear_matrix(n_out, n_in, |i| i as f64 * scale)
}

/// Bilinear resize of `maps` (`[B, C, h, w]`) to `[B, C, height, width]`
/// (`align_corners = false`).
pub fn upsample_bilinear(maps: Tensor<4>, height: usize, width: usize) -> Tensor<4> {
    resize(maps, height, width, interpolation_matrix)
}

/// Bilinear resize of `maps` (`[B, C, h, w]`) to `[B, C, height, width]`
/// with `align_corners = true`.
pub fn resize_bilinear_aligned(maps: Tensor<4>, height: usize, width: usize) -> Tensor<4> {
    resize(maps, height, width, aligned_interpolation_matrix)
}

fn resize(
    maps: Tensor<4>,
    height: usize,
    width: usize,
    matrix: fn(usize, usize) -> Vec<f32>,
) -> Tensor<4> {
    let [batch, channels, h, w] = maps.dims();
    let device: Device = maps.device();
    let dtype = maps.dtype();
    let rows = Tensor::<2>::from_data(TensorData::new(matrix(height, h), [height, h]), &device)
        .cast(dtype);
    let cols =
        Tensor::<2>::from_data(TensorData::new(matrix(width, w), [width, w]), &device).cast(dtype);
    let rows = rows
        .reshape([1, 1, height, h])
        .expand([batch, channels, height, h]);
    let cols_t = cols
        .transpose()
        .reshape([1, 1, w, width])
        .expand([batch, channels, w, width]);
    rows.matmul(maps).matmul(cols_t)
}

/// RAFT's convex upsampling of a one-channel map `[B, 1, h, w]` by
/// `factor`: each output pixel is a softmax-weighted combination of the 3x3
/// neighbourhood (zero outside) of its coarse pixel, scaled by `factor`.
/// `mask` is `[B, 9 factor^2, h, w]`, laid out as the official code reads
/// it (`[9, factor, factor]` per pixel).
pub fn convex_upsample(map: Tensor<4>, mask: Tensor<4>, factor: usize) -> Tensor<4> {
    let [batch, _, h, w] = map.dims();
    let weights = softmax(mask.reshape([batch, 9, factor, factor, h, w]), 1);
    let padded = (map * factor as f64).pad((1, 1, 1, 1), PadMode::Constant(0.0));
    let taps = (0..3)
        .flat_map(|dy| (0..3).map(move |dx| (dy, dx)))
        .map(|(dy, dx)| padded.clone().narrow(2, dy, h).narrow(3, dx, w))
        .collect();
    let neighbours: Tensor<6> = Tensor::cat(taps, 1).reshape([batch, 9, 1, 1, h, w]);
    // Interleaving before the sum (`[B, 9, h, f, w, f]`) gives the same
    // values as summing first; summing first made burn's wgpu backend
    // return wrong gradients for batches of more than one item.
    (weights * neighbours)
        .permute([0, 1, 4, 2, 5, 3])
        .sum_dim(1)
        .reshape([batch, 1, h * factor, w * factor])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::{assert_close, tensor4, values};

    #[test]
    fn matrix_matches_pytorch_align_corners_false() {
        // torch.nn.functional.interpolate([0, 1], size=4, mode="linear",
        // align_corners=False) = [0, 0.25, 0.75, 1].
        let m = interpolation_matrix(4, 2);
        assert_close(&m, &[1.0, 0.0, 0.75, 0.25, 0.25, 0.75, 0.0, 1.0], 1e-6);
        // Rows sum to 1.
        let m = interpolation_matrix(13, 4);
        for row in m.chunks(4) {
            assert!((row.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn aligned_matrix_matches_pytorch_align_corners_true() {
        // interpolate([0, 1], size=3, mode="linear", align_corners=True) = [0, 0.5, 1].
        let m = aligned_interpolation_matrix(3, 2);
        assert_close(&m, &[1.0, 0.0, 0.5, 0.5, 0.0, 1.0], 1e-6);
        // Downsampling 5 -> 3 keeps the ends and the centre.
        let m = aligned_interpolation_matrix(3, 5);
        let picked: Vec<usize> = m
            .chunks(5)
            .map(|row| row.iter().position(|w| *w == 1.0).expect("exact sample"))
            .collect();
        assert_eq!(picked, [0, 2, 4]);
    }

    #[test]
    fn upsamples_separably() {
        let device = Device::flex();
        let maps = tensor4(&[0.0, 1.0, 2.0, 3.0], [1, 1, 2, 2], &device);
        let up = upsample_bilinear(maps, 4, 4);
        assert_eq!(up.dims(), [1, 1, 4, 4]);
        // Rows [0, .25, .75, 1] x 2 + columns [0, .25, .75, 1].
        let axis = [0.0, 0.25, 0.75, 1.0];
        let want: Vec<f32> = axis
            .iter()
            .flat_map(|r| axis.iter().map(move |c| 2.0 * r + c))
            .collect();
        assert_close(&values(up), &want, 1e-6);
    }
}
