//! The range term: how far the student's disparities lie outside
//! `[0, W - 1]`, the values a pair of width `W` can have (conventions §2:
//! disparity is a non-negative magnitude, and a pixel matched `W` or more
//! columns away is in no view). It is zero for every plausible prediction,
//! so it leaves the paper's loss unchanged there; a prediction that has left
//! the range, where every warp reads the image border and the masks vanish,
//! still gets a gradient back toward it.
//!
//! The view term is the same per pixel: how far each warp lands outside
//! the target image. A disparity plausible for the width can still be too
//! large for its column (more than `x` for a target on the right); its warp
//! reads the clamped border, has no photometric gradient, and is out of
//! both masks. Zero where every warp lands inside; at a true disparity
//! larger than the column (a point the target's frame does not show, on a
//! strip as wide as the disparity along one border) it pulls toward the
//! edge, a bias the paper's loss does not have, which is why it is a
//! separate weight.

use burn::tensor::Tensor;
use mbs_core::geometry::Side;

use super::warp::sample_columns;

/// `mean(max(0, -d) + max(0, d - (W - 1)))` over the `[B, 1, H, W]` map, in
/// pixels.
pub fn out_of_range(disparity: Tensor<4>) -> Tensor<1> {
    let width = disparity.dims()[3];
    let below = disparity.clone().neg().clamp_min(0.0);
    let above = (disparity - (width - 1) as f64).clamp_min(0.0);
    (below + above).mean()
}

/// `mean(max(0, -c) + max(0, c - (W - 1)))` over the `[B, 1, H, W]` map,
/// where `c` is the column each pixel samples in its target ([`sample_columns`]):
/// how far (px) the warps land outside the target image.
pub fn out_of_view(disparity: Tensor<4>, sides: &[Side]) -> Tensor<1> {
    // The same hinge as the range term, on the columns instead of the
    // disparities (same width).
    out_of_range(sample_columns(disparity, sides))
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

    #[test]
    fn the_view_term_pulls_warps_that_leave_the_target_back_to_its_edge() {
        let device = Device::flex().autodiff();
        // W = 4, target on the right: columns x - d = -0.5, 0.5, -1.5, 5.
        let d = tensor4(&[0.5, 0.5, 3.5, -2.0], [1, 1, 1, 4], &device).require_grad();
        let term = out_of_view(d.clone(), &[Side::Right]);
        // (0.5 + 0 + 1.5 + 2) / 4: the plausible-for-the-width 3.5 px at x = 2 counts.
        assert_close(&values(term.clone().reshape([1, 1, 1, 1])), &[1.0], 1e-5);
        let grads = term.backward();
        let grad = values(d.grad(&grads).expect("d requires grad"));
        // Descent lowers the disparities that overshoot the left edge and
        // raises the negative one; the pixel that lands inside feels nothing.
        assert_close(&grad, &[0.25, 0.0, 0.25, -0.25], 1e-6);
        // A left target samples x + d: the mirror image of the same verdicts.
        let d = tensor4(&[3.5, 2.0, 0.0, 1.0], [1, 1, 1, 4], &device);
        let term = out_of_view(d, &[Side::Left]);
        // Columns 3.5, 3, 2, 4: overshoots 0.5, 0, 0, 1.
        assert_close(&values(term.reshape([1, 1, 1, 1])), &[0.375], 1e-5);
    }
}
