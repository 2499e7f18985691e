//! Photometric error map `P = alpha (1 - SSIM)/2 + (1 - alpha) |I_r - Î_r|`
//! (channel mean), with SSIM on a box window with reflection padding.

use burn::tensor::Tensor;
use burn::tensor::ops::PadMode;

/// SSIM stabilisers for images in `[0, 1]`: `(0.01)^2` and `(0.03)^2`.
const C1: f64 = 0.01 * 0.01;
const C2: f64 = 0.03 * 0.03;

/// Sums of `window` consecutive values along `dim` (a cumulative sum and
/// one difference: O(1) per output whatever the window; burn's
/// `avg_pool2d` costs O(window) and is 8x slower here at 7).
fn window_sums(tensor: Tensor<4>, dim: usize, window: usize) -> Tensor<4> {
    let outputs = tensor.dims()[dim] + 1 - window;
    let mut zero_shape = tensor.dims();
    zero_shape[dim] = 1;
    let zero = Tensor::<4>::zeros(zero_shape, &tensor.device());
    // prefix[i] = sum of the first i values.
    let prefix = Tensor::cat(vec![zero, tensor.cumsum(dim)], dim);
    prefix.clone().narrow(dim, window, outputs) - prefix.narrow(dim, 0, outputs)
}

/// Means over every `window x window` box that fits in `tensor` (an
/// output `window - 1` smaller in both image dimensions).
fn window_means(tensor: Tensor<4>, window: usize) -> Tensor<4> {
    let rows = window_sums(tensor, 2, window);
    window_sums(rows, 3, window) / (window * window) as f64
}

/// Per-pixel, per-channel SSIM of `x` and `y` (`[B, C, H, W]`, values in
/// `[0, 1]`) on an odd `window x window` box with reflection padding, as in
/// monodepth2 (whose window is 3; the S3 authors' toolbox uses 7).
///
/// # Panics
/// When the shapes differ or `window` is larger than `2 * min(H, W) - 1`
/// (reflection padding needs `window / 2 < min(H, W)`).
pub fn ssim(x: Tensor<4>, y: Tensor<4>, window: usize) -> Tensor<4> {
    // The images, centred on 0.5 (the (co)variances are the same, with less
    // f32 cancellation in E[x^2] - E[x]^2), are padded once: products of
    // reflected pixels are the reflected products, so each moment is
    // filtered without a padding of its own.
    let pad = window / 2;
    let reflect = |image: Tensor<4>| (image - 0.5).pad((pad, pad, pad, pad), PadMode::Reflect);
    let (x, y) = (reflect(x), reflect(y));
    let mean = |moment: Tensor<4>| window_means(moment, window);
    let (centred_x, centred_y) = (mean(x.clone()), mean(y.clone()));
    let sigma_x = mean(x.clone() * x.clone()) - centred_x.clone() * centred_x.clone();
    let sigma_y = mean(y.clone() * y.clone()) - centred_y.clone() * centred_y.clone();
    let sigma_xy = mean(x * y) - centred_x.clone() * centred_y.clone();
    let (mu_x, mu_y) = (centred_x + 0.5, centred_y + 0.5);
    let numerator = (mu_x.clone() * mu_y.clone() * 2.0 + C1) * (sigma_xy * 2.0 + C2);
    let denominator = (mu_x.clone() * mu_x + mu_y.clone() * mu_y + C1) * (sigma_x + sigma_y + C2);
    numerator / denominator
}

/// Photometric error map `[B, 1, H, W]` between the reference and its
/// reconstruction: `alpha * clamp((1 - SSIM) / 2, 0, 1) + (1 - alpha) * |I_r - Î_r|`,
/// averaged over channels.
pub fn photometric_map(
    reference: Tensor<4>,
    reconstructed: Tensor<4>,
    alpha: f64,
    window: usize,
) -> Tensor<4> {
    let dissimilarity = (ssim(reference.clone(), reconstructed.clone(), window).neg() + 1.0)
        .div_scalar(2.0)
        .clamp(0.0, 1.0);
    let l1 = (reference - reconstructed).abs();
    (dissimilarity * alpha + l1 * (1.0 - alpha)).mean_dim(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;
    use mbs_nets::test_util::{assert_close, tensor4, values};

    const X: [f32; 20] = [
        0.1, 0.5, 0.9, 0.3, 0.2, 0.4, 0.8, 0.6, 0.1, 0.7, 0.9, 0.2, 0.3, 0.5, 0.6, 0.0, 0.4, 1.0,
        0.8, 0.3,
    ];
    const Y: [f32; 20] = [
        0.2, 0.4, 0.7, 0.3, 0.1, 0.5, 0.9, 0.5, 0.2, 0.6, 0.8, 0.1, 0.4, 0.6, 0.4, 0.1, 0.5, 0.9,
        0.7, 0.2,
    ];

    #[test]
    fn ssim_of_constant_images_is_the_luminance_term() {
        let device = Device::flex();
        let x = Tensor::<4>::full([1, 1, 8, 8], 0.2, &device);
        let y = Tensor::<4>::full([1, 1, 8, 8], 0.6, &device);
        // (2ab + C1) / (a^2 + b^2 + C1) = 0.2401 / 0.4001; the f32 variance
        // E[x^2] - E[x]^2 cancels to ~1e-8 (against C2 = 9e-4).
        let s = values(ssim(x.clone(), y, 7));
        assert_close(&s, &[0.600_1; 64], 5e-5);
        // Identical images: SSIM 1, photometric error 0.
        let p = values(photometric_map(x.clone(), x, 0.85, 7));
        assert_close(&p, &[0.0; 64], 1e-6);
    }

    #[test]
    fn ssim_and_photometric_match_a_reference_on_a_4x5_pair() {
        // Reference values from a direct numpy implementation (3x3 box,
        // numpy.pad mode="reflect", C1 = 1e-4, C2 = 9e-4).
        let device = Device::flex();
        let x = tensor4(&X, [1, 1, 4, 5], &device);
        let y = tensor4(&Y, [1, 1, 4, 5], &device);
        let s = values(ssim(x.clone(), y.clone(), 3));
        let expected_ssim = [
            0.940_509_4,
            0.870_703_6,
            0.916_827_9,
            0.916_287,
            0.908_349_6,
            0.941_750_3,
            0.909_119_8,
            0.899_870_2,
            0.854_202,
            0.854_672_3,
            0.949_989_4,
            0.945_992_2,
            0.934_608_6,
            0.899_412_8,
            0.880_769_7,
            0.945_519_5,
            0.953_192_5,
            0.923_356_8,
            0.827_452_2,
            0.671_739,
        ];
        assert_close(&s, &expected_ssim, 2e-4);
        let p = values(photometric_map(x, y, 0.85, 3));
        let expected_p = [
            0.040_283_5,
            0.069_951_0,
            0.065_348_2,
            0.035_578_0,
            0.053_951_4,
            0.039_756_1,
            0.053_624_1,
            0.057_555_2,
            0.076_964_1,
            0.076_764_3,
            0.036_254_5,
            0.037_953_3,
            0.042_791_3,
            0.057_749_6,
            0.080_672_9,
            0.038_154_2,
            0.034_893_2,
            0.047_573_4,
            0.088_332_8,
            0.154_510_9,
        ];
        assert_close(&p, &expected_p, 1e-4);
    }

    #[test]
    fn photometric_map_averages_channels() {
        let device = Device::flex();
        // Channel 0 differs by 0.2 everywhere, channel 1 is equal: with
        // alpha = 0 the map is the L1 channel mean, 0.1.
        let a = Tensor::<4>::full([1, 2, 3, 3], 0.5, &device);
        let mut shifted = vec![0.7f32; 9];
        shifted.extend([0.5f32; 9]);
        let b = tensor4(&shifted, [1, 2, 3, 3], &device);
        let p = photometric_map(a, b, 0.0, 3);
        assert_eq!(p.dims(), [1, 1, 3, 3]);
        assert_close(&values(p), &[0.1; 9], 1e-6);
    }
}
