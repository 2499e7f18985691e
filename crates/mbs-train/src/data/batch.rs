//! The tensors of one S3 step: a host batch ([`mbs_batch::HostBatch`])
//! on the device, with the student's input augmented by the draws of its
//! step.

use burn::tensor::{Device, Tensor};
use mbs_core::Side;

use mbs_batch::rng::{Stream, step_rng};
use mbs_batch::sampling::Triplet;
use mbs_batch::{HostBatch, share};

use crate::augment::{self, AugmentConfig};
use mbs_nets::host::chw_tensor;

/// One batch for [`crate::S3Trainer::step`]. Images are `[B, 3, H, W]` in `[0, 1]`
/// on a plain (non-autodiff) device.
#[derive(Debug, Clone)]
pub struct StepBatch {
    /// Clean reference images.
    pub reference: Tensor<4>,
    /// Clean student targets.
    pub student_target: Tensor<4>,
    /// Clean teacher targets.
    pub teacher_target: Tensor<4>,
    /// Augmented reference images (the student's input).
    pub augmented_reference: Tensor<4>,
    /// Augmented student targets (the student's input).
    pub augmented_target: Tensor<4>,
    /// Side of each student target.
    pub student_sides: Vec<Side>,
    /// Side of each teacher target.
    pub teacher_sides: Vec<Side>,
    /// Baseline ratio `r = B_s / B_t` of each item.
    pub ratios: Vec<f64>,
}

impl StepBatch {
    /// The tensors of `host`'s items on `device`, with the student's input
    /// augmented by their draws of `config` for the step's whole batch
    /// from [`step_rng`]`(seed, step, Augment)`, so that a share of a
    /// batch is augmented as the same items of the whole batch are.
    pub fn from_host(host: HostBatch, device: &Device, config: &AugmentConfig, seed: u64) -> Self {
        let shape = [host.len(), 3, host.height, host.width];
        let tensor = |data: Vec<f32>| chw_tensor(data, shape, device);
        let reference = tensor(host.reference);
        let student_target = tensor(host.student_target);
        let mut rng = step_rng(seed, host.step, Stream::Augment);
        let draws = config
            .draw(host.batch_size, host.height, host.width, &mut rng)
            .of_items(host.items, host.height * host.width);
        let (augmented_reference, augmented_target) =
            augment::apply(&draws, reference.clone(), student_target.clone());
        StepBatch {
            reference,
            student_target,
            teacher_target: tensor(host.teacher_target),
            augmented_reference,
            augmented_target,
            student_sides: host.triplets.iter().map(Triplet::student_side).collect(),
            teacher_sides: host.triplets.iter().map(Triplet::teacher_side).collect(),
            ratios: host.ratios,
        }
    }

    /// Splits the items into `parts` consecutive shares
    /// ([`mbs_batch::share`]); `parts` is at most the number of items.
    pub fn split(self, parts: usize) -> Vec<StepBatch> {
        let items = self.reference.dims()[0];
        let parts = parts.clamp(1, items.max(1));
        (0..parts)
            .map(|part| {
                let range = share(items, parts, part);
                let take = |tensor: &Tensor<4>| tensor.clone().narrow(0, range.start, range.len());
                StepBatch {
                    reference: take(&self.reference),
                    student_target: take(&self.student_target),
                    teacher_target: take(&self.teacher_target),
                    augmented_reference: take(&self.augmented_reference),
                    augmented_target: take(&self.augmented_target),
                    student_sides: self.student_sides[range.clone()].to_vec(),
                    teacher_sides: self.teacher_sides[range.clone()].to_vec(),
                    ratios: self.ratios[range].to_vec(),
                }
            })
            .collect()
    }

    /// The same batch on `device`.
    pub fn to_device(self, device: &Device) -> StepBatch {
        StepBatch {
            reference: self.reference.to_device(device),
            student_target: self.student_target.to_device(device),
            teacher_target: self.teacher_target.to_device(device),
            augmented_reference: self.augmented_reference.to_device(device),
            augmented_target: self.augmented_target.to_device(device),
            ..self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;

    #[test]
    fn split_shares_are_consecutive_and_differ_by_at_most_one_item() {
        let device = Device::flex();
        let items = 5;
        let values: Vec<f32> = (0..items * 12).map(|i| (i / 12) as f32).collect();
        let numbered = mbs_nets::test_util::tensor4(&values, [items, 3, 2, 2], &device);
        let batch = StepBatch {
            reference: numbered.clone(),
            student_target: numbered.clone(),
            teacher_target: numbered.clone(),
            augmented_reference: numbered.clone(),
            augmented_target: numbered,
            student_sides: vec![Side::Right; items],
            teacher_sides: vec![Side::Left; items],
            ratios: (0..items).map(|i| i as f64).collect(),
        };
        let shares = batch.split(3);
        let firsts: Vec<Vec<f32>> = shares
            .iter()
            .map(|share| {
                let values = mbs_nets::test_util::values(share.augmented_target.clone());
                values.iter().step_by(12).copied().collect()
            })
            .collect();
        assert_eq!(firsts, [vec![0.0, 1.0], vec![2.0, 3.0], vec![4.0]]);
        let ratios: Vec<Vec<f64>> = shares.iter().map(|s| s.ratios.clone()).collect();
        assert_eq!(ratios, [vec![0.0, 1.0], vec![2.0, 3.0], vec![4.0]]);
        assert!(
            shares
                .iter()
                .all(|s| s.teacher_sides.iter().all(|&side| side == Side::Left))
        );
    }
}
