//! Mirroring for networks that only know "target on the right" (conventions §2):
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
    use crate::test_util::{assert_close, tensor4, values};
    use burn::tensor::Device;

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
