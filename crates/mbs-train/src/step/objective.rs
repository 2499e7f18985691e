//! The step's arithmetic on one share of a batch, wherever it runs:
//! teacher and student forward passes in the run's precision, the S3 loss
//! of the student's predictions, and the gradients of the share's loss
//! with its values read back ([`LossValues`]).

use burn::optim::GradientsParams;
use burn::tensor::{FloatDType, Tensor};

use super::sequence_weights;
use crate::data::StepBatch;
use crate::error::TrainError;
use crate::losses::{LossInputs, LossOutput, S3Loss, Terms};
use crate::precision::{Precision, cast_network};
use crate::supervision::{Supervision, measure};
use mbs_nets::host::read_scalar;
use mbs_nets::{Backbone, predict, predict_sequence};

/// What the student minimises: the S3 loss of its final prediction plus
/// the weighted losses of its earlier ones. Plain settings, shared by the
/// threads of a data-parallel step.
#[derive(Debug, Clone)]
pub(super) struct Objective {
    pub(super) loss: S3Loss,
    pub(super) sequence_gamma: f64,
    pub(super) final_prediction_only: bool,
    pub(super) precision: Precision,
    /// The geometry term's weight at the step being taken.
    pub(super) geometry_weight: f64,
    /// The teacher's pseudo-labels come from its test iterations.
    pub(super) teacher_test_iters: bool,
}

/// The loss values of a batch (or of a share of one), read back.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct LossValues {
    pub(super) total: f32,
    pub(super) terms: Terms<f32>,
    pub(super) supervision: Supervision,
}

impl Objective {
    /// Teacher and student predictions and the loss on `batch`, on the
    /// student's device (the student's own gradient path when it has one),
    /// the networks in the run's precision and the loss in f32.
    pub(super) fn forward<B: Backbone>(
        &self,
        teacher: &B,
        student: &B,
        batch: StepBatch,
    ) -> Result<(LossOutput, Tensor<1>), TrainError> {
        match self.precision.compute_dtype() {
            None => self.forward_in(teacher, student, batch, None),
            Some(dtype) => self.forward_in(
                &cast_network(teacher.clone(), dtype),
                &cast_network(student.clone(), dtype),
                batch,
                Some(dtype),
            ),
        }
    }

    /// [`Self::forward`] with networks whose parameters are in `dtype`
    /// (`None`: f32): their inputs are cast to it and their predictions
    /// back to f32. With the loss, the step's supervision statistics
    /// ([`measure`]) on the device.
    fn forward_in<B: Backbone>(
        &self,
        teacher: &B,
        student: &B,
        batch: StepBatch,
        dtype: Option<FloatDType>,
    ) -> Result<(LossOutput, Tensor<1>), TrainError> {
        let input = |image: Tensor<4>| match dtype {
            Some(dtype) => image.cast(dtype),
            None => image,
        };
        let StepBatch {
            reference,
            student_target,
            teacher_target,
            augmented_reference,
            augmented_target,
            student_sides,
            teacher_sides,
            ratios,
        } = batch;
        // Only the geometry term reads the teacher (Table 3 (A) runs without it).
        let teacher_disparity = if self.loss.config().geometry {
            let (reference, target) = (input(reference.clone()), input(teacher_target.clone()));
            match self.teacher_test_iters {
                true => predict(teacher, reference, target, &teacher_sides),
                false => predict_sequence(teacher, reference, target, &teacher_sides)
                    .pop()
                    .ok_or_else(|| TrainError::Shape("the teacher predicted nothing".into()))?,
            }
            .cast(FloatDType::F32)
        } else {
            let [batch, _, height, width] = reference.dims();
            Tensor::zeros([batch, 1, height, width], &reference.device())
        };
        let mut predictions: Vec<_> = predict_sequence(
            student,
            input(augmented_reference),
            input(augmented_target),
            &student_sides,
        )
        .into_iter()
        .map(|prediction| prediction.cast(FloatDType::F32))
        .collect();
        let weights = sequence_weights(
            predictions.len(),
            self.sequence_gamma,
            self.final_prediction_only,
        );
        let student_disparity = predictions
            .pop()
            .ok_or_else(|| TrainError::Shape("the student returned no prediction".into()))?;
        let final_prediction = student_disparity.clone();
        let sides = student_sides.clone();
        let inputs = LossInputs {
            reference,
            student_target,
            teacher_target,
            student_disparity,
            teacher_disparity,
            student_sides,
            teacher_sides,
            ratios,
            geometry_weight: self.geometry_weight,
        };
        // The final prediction's terms are the ones reported; the earlier
        // predictions add their weighted totals.
        let earlier = predictions
            .into_iter()
            .zip(weights)
            .filter(|(_, weight)| *weight > 0.0)
            .collect();
        let out = self.loss.compute_sequence(inputs, earlier)?;
        let measured = measure(
            final_prediction,
            &sides,
            out.student_mask.clone(),
            out.teacher_mask.clone(),
        );
        Ok((out, measured))
    }

    /// The gradients of `weight` times the loss of `batch` for `student`
    /// (on an autodiff device, with `teacher` and `batch` on the same
    /// device), and the unweighted loss values. An f16 run passes its loss
    /// scale in `weight`.
    pub(super) fn gradients<B: Backbone>(
        &self,
        teacher: &B,
        student: &B,
        batch: StepBatch,
        weight: f64,
    ) -> Result<(GradientsParams, LossValues), TrainError> {
        let (out, measured) = self.forward(teacher, student, batch)?;
        let values = LossValues {
            total: read_scalar(out.total.clone(), "the loss")?,
            terms: out
                .terms
                .try_map(|term, value| read_scalar(value, term.name()))?,
            supervision: Supervision::read(measured)?,
        };
        let total = if weight == 1.0 {
            out.total
        } else {
            out.total.mul_scalar(weight)
        };
        Ok((
            GradientsParams::from_grads(total.backward(), student),
            values,
        ))
    }
}

impl LossValues {
    /// The sum of each share's values times its weight.
    pub(super) fn weighted_sum(shares: &[(LossValues, f64)]) -> Self {
        let sum = |value: &dyn Fn(&LossValues) -> Option<f32>| {
            shares
                .iter()
                .map(|(values, weight)| value(values).map(|v| v * *weight as f32))
                .sum::<Option<f32>>()
        };
        Self {
            total: sum(&|v| Some(v.total)).unwrap_or_default(),
            terms: Terms::from_fn(|term| sum(&|v| v.terms.value(term))),
            supervision: Supervision::combine(
                &shares
                    .iter()
                    .map(|(values, weight)| (values.supervision, *weight))
                    .collect::<Vec<_>>(),
            ),
        }
    }
}
