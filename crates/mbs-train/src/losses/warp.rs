//! Differentiable horizontal warp: reconstruct the reference image from a
//! target image and a disparity on the reference grid.

use burn::tensor::{Int, Tensor, TensorData};
use mbs_core::geometry::Side;

/// Samples `target` (`[B, C, H, W]`) at column `x - d` (target right of the
/// reference) or `x + d` (target left), per batch item as given by `sides`,
/// with linear interpolation along x. `disparity` is `[B, 1, H, W]` on the
/// reference grid. Coordinates outside the image are clamped to the border
/// (border padding, as monodepth2's `grid_sample`); the result is
/// differentiable in `disparity` (and in `target`).
///
/// # Panics
/// When the shapes disagree, `sides.len() != B`, or `W < 2`; the loss entry
/// point [`crate::losses::S3Loss::compute`] checks these first.
pub fn warp_to_reference(target: Tensor<4>, disparity: Tensor<4>, sides: &[Side]) -> Tensor<4> {
    let [batch, channels, height, width] = target.dims();
    assert!(width >= 2, "warp needs an image at least 2 pixels wide");
    assert_eq!(sides.len(), batch, "one side per batch item");
    let x = sample_columns(disparity, sides).clamp(0.0, (width - 1) as f64);
    // The left sample column is constant for the gradient; the interpolation
    // weight carries the derivative in d.
    let left = x.clone().detach().floor().clamp_max((width - 2) as f64);
    let weight = x - left.clone();
    let left = left.int().expand([batch, channels, height, width]);
    let right = left.clone() + 1;
    let left_values = target.clone().gather(3, left);
    let right_values = target.gather(3, right);
    left_values * (weight.clone().neg() + 1.0) + right_values * weight
}

/// The column each reference pixel samples in its target, `x - d` (target
/// on the right) or `x + d` (on the left), before any clamping; `disparity`
/// is `[B, 1, H, W]` and `sides.len() == B`.
pub fn sample_columns(disparity: Tensor<4>, sides: &[Side]) -> Tensor<4> {
    let [batch, _, _, width] = disparity.dims();
    let device = disparity.device();
    let columns = Tensor::<1, Int>::arange(0..width as i64, &device)
        .float()
        .reshape([1, 1, 1, width]);
    let signs: Vec<f32> = sides.iter().map(|side| side_sign(*side)).collect();
    let signs =
        Tensor::<1>::from_data(TensorData::new(signs, [batch]), &device).reshape([batch, 1, 1, 1]);
    columns - disparity * signs
}

/// 1 where a pixel's sample column lies inside the target image, 0 where
/// the warp leaves it and reads the clamped border instead of a match (no
/// gradient); `[B, 1, H, W]`.
pub fn lands_inside(disparity: Tensor<4>, sides: &[Side]) -> Tensor<4> {
    let width = disparity.dims()[3];
    let columns = sample_columns(disparity.detach(), sides);
    let after_start = columns.clone().greater_equal_elem(0.0).float();
    let before_end = columns.lower_equal_elem((width - 1) as f64).float();
    after_start * before_end
}

/// The share of pixels whose warp leaves the target image (no gradient).
pub fn outside_share(disparity: Tensor<4>, sides: &[Side]) -> Tensor<1> {
    (lands_inside(disparity, sides).neg() + 1.0).mean()
}

/// +1 for a target on the right (sample at `x - d`), -1 on the left (`x + d`).
fn side_sign(side: Side) -> f32 {
    match side {
        Side::Right => 1.0,
        Side::Left => -1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;
    use mbs_nets::mirror::mirror_left;
    use mbs_nets::test_util::{assert_close, tensor4, values};

    #[test]
    fn integer_and_fractional_shifts_right_and_left() {
        let device = Device::flex();
        // One row, W = 5, values 0, 10, 20, 30, 40.
        let target = tensor4(&[0.0, 10.0, 20.0, 30.0, 40.0], [1, 1, 1, 5], &device);
        let d = tensor4(&[0.0, 1.0, 0.5, 2.25, 0.0], [1, 1, 1, 5], &device);
        // Right target: x - d = 0, 0, 1.5, 0.75, 4.
        let right = warp_to_reference(target.clone(), d.clone(), &[Side::Right]);
        assert_close(&values(right), &[0.0, 0.0, 15.0, 7.5, 40.0], 1e-5);
        // Left target: x + d = 0, 2, 2.5, 5.25 -> clamped to 4, 4.
        let left = warp_to_reference(target, d, &[Side::Left]);
        assert_close(&values(left), &[0.0, 20.0, 25.0, 40.0, 40.0], 1e-5);
    }

    #[test]
    fn gradient_in_disparity_matches_finite_differences() {
        let device = Device::flex().autodiff();
        let row = [0.1f32, 0.7, 0.3, 0.9, 0.2, 0.5];
        let d0 = [0.3f32, 1.2, 0.6, 2.7, 1.4, 0.8];
        let eval = |d: &[f32]| -> f32 {
            let target = tensor4(&row, [1, 1, 1, 6], &device);
            let dt = tensor4(d, [1, 1, 1, 6], &device);
            let warped = warp_to_reference(target, dt, &[Side::Right]);
            // A non-trivial scalar: weighted sum of the warped row.
            let weights = tensor4(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], [1, 1, 1, 6], &device);
            values((warped * weights).sum().reshape([1, 1, 1, 1]))[0]
        };
        let target = tensor4(&row, [1, 1, 1, 6], &device);
        let dt = tensor4(&d0, [1, 1, 1, 6], &device).require_grad();
        let weights = tensor4(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], [1, 1, 1, 6], &device);
        let loss = (warp_to_reference(target, dt.clone(), &[Side::Right]) * weights).sum();
        let grads = loss.backward();
        let analytic = values(dt.grad(&grads).expect("d requires grad"));
        let h = 1e-2f32;
        for i in 0..6 {
            let mut plus = d0;
            let mut minus = d0;
            plus[i] += h;
            minus[i] -= h;
            let numeric = (eval(&plus) - eval(&minus)) / (2.0 * h);
            // Piecewise linear in d, no kink within +-h of these points: exact up to rounding.
            assert!(
                (analytic[i] - numeric).abs() < 1e-3,
                "pixel {i}: {} vs {numeric}",
                analytic[i]
            );
        }
        // Hand value at x = 3: x - d = 0.3, slope -(row[1] - row[0]) * weight 4 = -2.4.
        assert!((analytic[3] + 2.4).abs() < 1e-5, "{}", analytic[3]);
    }

    #[test]
    fn a_mirrored_left_pair_is_a_right_pair() {
        let device = Device::flex();
        // Reference pixel x is seen at x + 1 in the left target.
        let reference = tensor4(&[0.1, 0.2, 0.4, 0.8, 0.9], [1, 1, 1, 5], &device);
        let target = tensor4(&[0.0, 0.1, 0.2, 0.4, 0.8], [1, 1, 1, 5], &device);
        let d = Tensor::<4>::ones([1, 1, 1, 5], &device);
        let direct = warp_to_reference(target.clone(), d.clone(), &[Side::Left]);
        // Mirrored: the target is now on the right, sampled at x - d.
        let flipped_ref = mirror_left(reference, &[Side::Left]);
        let flipped_target = mirror_left(target, &[Side::Left]);
        assert_close(
            &values(flipped_ref.clone()),
            &[0.9, 0.8, 0.4, 0.2, 0.1],
            0.0,
        );
        let warped = warp_to_reference(flipped_target, d, &[Side::Right]);
        // Interior columns reconstruct the mirrored reference exactly.
        assert_close(
            &values(warped.clone()).as_slice()[1..],
            &values(flipped_ref)[1..],
            1e-6,
        );
        // Flipping the mirrored reconstruction back equals the direct left warp.
        assert_close(
            &values(mirror_left(warped, &[Side::Left])),
            &values(direct),
            1e-6,
        );
    }
}
