//! Mirroring for networks that only know "target on the right" (SPEC §2):
//! a pair whose target lies left of the reference is flipped horizontally,
//! and the predicted disparity is flipped back onto the reference grid.

use burn::tensor::Tensor;
use mbs_core::geometry::Side;

/// Flips along x every batch item (`[B, ...]`, x last) whose side is
/// [`Side::Left`]; right-side items pass unchanged. Mirroring is its own
/// inverse, so this both prepares a pair and restores a disparity.
///
/// # Panics
/// When `sides.len()` differs from the batch size.
pub fn mirror_left<const D: usize>(tensor: Tensor<D>, sides: &[Side]) -> Tensor<D> {
    let batch = tensor.dims()[0];
    assert_eq!(sides.len(), batch, "one side per batch item");
    if sides.iter().all(|side| *side == Side::Right) {
        return tensor;
    }
    if sides.iter().all(|side| *side == Side::Left) {
        return tensor.flip([D as isize - 1]);
    }
    let items = sides
        .iter()
        .enumerate()
        .map(|(i, side)| {
            let item = tensor.clone().narrow(0, i, 1);
            match side {
                Side::Left => item.flip([D as isize - 1]),
                Side::Right => item,
            }
        })
        .collect();
    Tensor::cat(items, 0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::losses::warp::warp_to_reference;
    use crate::test_util::{assert_close, tensor4, values};
    use burn::tensor::Device;

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

    #[test]
    fn mixed_batches_flip_only_left_items() {
        let device = Device::flex();
        let batch = tensor4(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], [2, 1, 1, 3], &device);
        let out = mirror_left(batch.clone(), &[Side::Right, Side::Left]);
        assert_close(&values(out.clone()), &[1.0, 2.0, 3.0, 6.0, 5.0, 4.0], 0.0);
        assert_close(
            &values(mirror_left(out, &[Side::Right, Side::Left])),
            &values(batch),
            0.0,
        );
    }
}
