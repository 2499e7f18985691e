//! Edge-aware first-order smoothness (paper eq. 3):
//! `|dx d| exp(-|dx I|) + |dy d| exp(-|dy I|)`, image gradients averaged
//! over channels.

use burn::tensor::Tensor;

/// Edge-aware smoothness of `disparity` (`[B, 1, H, W]`) guided by `image`
/// (`[B, C, H, W]`): the mean over horizontal neighbour pairs of
/// `|d(x+1) - d(x)| exp(-|I(x+1) - I(x)|)` plus the same mean over vertical
/// pairs. With `normalise`, each map is first divided by its mean, as
/// monodepth2 does; the paper's eq. 3 does not, so the default run leaves
/// it off. Returns a one-element tensor.
pub fn edge_aware_smoothness(disparity: Tensor<4>, image: Tensor<4>, normalise: bool) -> Tensor<1> {
    let [_, _, height, width] = disparity.dims();
    let disparity = if normalise {
        disparity.clone() / (disparity.mean_dims(&[2, 3]) + 1e-7)
    } else {
        disparity
    };
    let along = |tensor: Tensor<4>, dim: usize, len: usize| {
        tensor.clone().narrow(dim, 1, len - 1) - tensor.narrow(dim, 0, len - 1)
    };
    let term = |dim: usize, len: usize| {
        let disparity_step = along(disparity.clone(), dim, len).abs();
        let image_step = along(image.clone(), dim, len).abs().mean_dim(1);
        (disparity_step * image_step.neg().exp()).mean()
    };
    term(3, width) + term(2, height)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;
    use mbs_nets::test_util::{tensor4, values};

    #[test]
    fn hand_computed_2x3_case() {
        let device = Device::flex();
        // d = [[0, 1, 3], [2, 2, 2]]; image (one channel) = [[0, 0, 1], [0, 0, 1]].
        let d = tensor4(&[0.0, 1.0, 3.0, 2.0, 2.0, 2.0], [1, 1, 2, 3], &device);
        let image = tensor4(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], [1, 1, 2, 3], &device);
        // x pairs: |1|e^0, |2|e^-1, 0, 0 -> mean (1 + 2/e) / 4.
        // y pairs: |2|, |1|, |1| with flat image -> mean 4/3.
        let expected = (1.0 + 2.0 / std::f32::consts::E) / 4.0 + 4.0 / 3.0;
        let got =
            values(edge_aware_smoothness(d.clone(), image.clone(), false).reshape([1, 1, 1, 1]))[0];
        assert!((got - expected).abs() < 1e-5, "{got} vs {expected}");
        // Normalised: the mean disparity is 10/6, so the term is divided by it.
        let got = values(edge_aware_smoothness(d, image, true).reshape([1, 1, 1, 1]))[0];
        assert!(
            (got - expected * 0.6).abs() < 1e-5,
            "{got} vs {}",
            expected * 0.6
        );
    }

    #[test]
    fn constant_disparity_is_perfectly_smooth() {
        let device = Device::flex();
        let d = Tensor::<4>::full([2, 1, 4, 5], 3.0, &device);
        let image = Tensor::<4>::random([2, 3, 4, 5], burn::tensor::Distribution::Default, &device);
        let got = values(edge_aware_smoothness(d, image, true).reshape([1, 1, 1, 1]))[0];
        assert!(got.abs() < 1e-7);
    }
}
