//! The range term: how far the student's disparities lie outside
//! `[0, W - 1]`, the values a pair of width `W` can have (conventions §2:
//! disparity is a non-negative magnitude, and a pixel matched `W` or more
//! columns away is in no view). It is zero for every plausible prediction,
//! so it leaves the paper's loss unchanged there; a prediction that has left
//! the range, where every warp reads the image border and the masks vanish,
//! still gets a gradient back toward it.

use burn::tensor::Tensor;

/// `mean(max(0, -d) + max(0, d - (W - 1)))` over the `[B, 1, H, W]` map, in
/// pixels.
pub fn out_of_range(disparity: Tensor<4>) -> Tensor<1> {
    let width = disparity.dims()[3];
    let below = disparity.clone().neg().clamp_min(0.0);
    let above = (disparity - (width - 1) as f64).clamp_min(0.0);
    (below + above).mean()
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;
    use mbs_nets::test_util::{assert_close, tensor4, values};

    #[test]
    fn zero_inside_the_range_and_pulls_back_from_outside() {
        let device = Device::flex().autodiff();
        // W = 4: the range is [0, 3].
        let d = tensor4(&[0.5, 2.0, -200.0, 7.5], [1, 1, 1, 4], &device).require_grad();
        let term = out_of_range(d.clone());
        // (0 + 0 + 200 + 4.5) / 4
        assert_close(&values(term.clone().reshape([1, 1, 1, 1])), &[51.125], 1e-4);
        let grads = term.backward();
        let grad = values(d.grad(&grads).expect("d requires grad"));
        // Gradient descent moves -200 up and 7.5 down; in-range pixels feel nothing.
        assert_close(&grad, &[0.0, 0.0, -0.25, 0.25], 1e-6);
    }
}
