//! The step's arithmetic on one share of a batch, wherever it runs:
//! teacher and student forward passes in the run's precision, the S3 loss
//! of the student's predictions, and the gradients of the share's loss
//! with its values read back ([`LossValues`]).

use burn::optim::GradientsParams;
use burn::tensor::{FloatDType, Tensor};

use super::PredictionWeights;
use crate::data::StepBatch;
use crate::error::TrainError;
use crate::losses::{LossInputs, LossOutput, S3Loss, Terms};
use crate::precision::{Precision, cast_network};
use crate::supervision::{Supervision, measure};
use mbs_core::Side;
use mbs_nets::host::read_scalar;
use mbs_nets::{Backbone, predict, predict_sequence};

/// What the student minimises: the S3 loss of its final prediction plus
/// the weighted losses of its earlier ones. Plain settings, shared by the
/// threads of a data-parallel step; what changes from step to step (the
/// geometry term's weight, the loss scale) is passed to each call.
#[derive(Debug, Clone)]
pub(super) struct Objective {
    pub(super) loss: S3Loss,
    pub(super) weights: PredictionWeights,
    pub(super) precision: Precision,
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
    /// the networks in the run's precision and the loss in f32, its
    /// geometry term weighted by `geometry_weight`.
    pub(super) fn forward<B: Backbone>(
        &self,
        teacher: &B,
        student: &B,
        batch: StepBatch,
        geometry_weight: f64,
    ) -> Result<(LossOutput, Tensor<1>), TrainError> {
        match self.precision.compute_dtype() {
            None => self.forward_in((teacher, student), batch, None, geometry_weight),
            Some(dtype) => self.forward_in(
                (
                    &cast_network(teacher.clone(), dtype),
                    &cast_network(student.clone(), dtype),
                ),
                batch,
                Some(dtype),
                geometry_weight,
            ),
        }
    }

    /// [`Self::forward`] with networks whose parameters are in `dtype`
    /// (`None`: f32): their inputs are cast to it and their predictions
    /// back to f32. With the loss, the step's supervision statistics
    /// ([`measure`]) on the device.
    fn forward_in<B: Backbone>(
        &self,
        (teacher, student): (&B, &B),
        batch: StepBatch,
        dtype: Option<FloatDType>,
        geometry_weight: f64,
    ) -> Result<(LossOutput, Tensor<1>), TrainError> {
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
        let clean_pair = (reference.clone(), teacher_target.clone());
        let teacher_disparity =
            self.teacher_disparity(teacher, clean_pair, &teacher_sides, dtype)?;
        let student_input = (augmented_reference, augmented_target);
        let (student_disparity, earlier) =
            self.student_predictions(student, student_input, &student_sides, dtype)?;
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
            geometry_weight,
        };
        let out = self.loss.compute_sequence(inputs, earlier)?;
        let measured = measure(
            final_prediction,
            &sides,
            out.student_mask.clone(),
            out.teacher_mask.clone(),
        );
        Ok((out, measured))
    }

    /// The teacher's pseudo-labels `d_t` (f32) on the clean pair
    /// `(reference, target)`, the teacher in `dtype`; zeros when the
    /// geometry term, their only reader, is off (Table 3 (A)).
    fn teacher_disparity<B: Backbone>(
        &self,
        teacher: &B,
        (reference, target): (Tensor<4>, Tensor<4>),
        sides: &[Side],
        dtype: Option<FloatDType>,
    ) -> Result<Tensor<4>, TrainError> {
        if !self.loss.config().geometry {
            let [batch, _, height, width] = reference.dims();
            return Ok(Tensor::zeros(
                [batch, 1, height, width],
                &reference.device(),
            ));
        }
        let (reference, target) = (in_dtype(reference, dtype), in_dtype(target, dtype));
        let disparity = match self.teacher_test_iters {
            true => predict(teacher, reference, target, sides),
            false => predict_sequence(teacher, reference, target, sides)
                .pop()
                .ok_or_else(|| TrainError::Shape("the teacher predicted nothing".into()))?,
        };
        Ok(disparity.cast(FloatDType::F32))
    }

    /// The student's predictions (f32) on its augmented pair `input`, the
    /// student in `dtype`: the final one, whose terms are the ones
    /// reported, and each earlier one whose sequence weight is not 0, with
    /// that weight (it adds its weighted total).
    fn student_predictions<B: Backbone>(
        &self,
        student: &B,
        (reference, target): (Tensor<4>, Tensor<4>),
        sides: &[Side],
        dtype: Option<FloatDType>,
    ) -> Result<(Tensor<4>, Vec<(Tensor<4>, f64)>), TrainError> {
        let (reference, target) = (in_dtype(reference, dtype), in_dtype(target, dtype));
        let mut predictions: Vec<_> = predict_sequence(student, reference, target, sides)
            .into_iter()
            .map(|prediction| prediction.cast(FloatDType::F32))
            .collect();
        let weights = self
            .weights
            .of(predictions.len(), student.initial_estimates());
        let last = predictions
            .pop()
            .ok_or_else(|| TrainError::Shape("the student returned no prediction".into()))?;
        let earlier = predictions
            .into_iter()
            .zip(weights)
            .filter(|(_, weight)| *weight > 0.0)
            .collect();
        Ok((last, earlier))
    }

    /// The gradients of `weight` times the loss of `batch` for `student`
    /// (on an autodiff device, with `teacher` and `batch` on the same
    /// device), its geometry term weighted by `geometry_weight`, and the
    /// unweighted loss values. An f16 run passes its loss scale in
    /// `weight`.
    pub(super) fn gradients<B: Backbone>(
        &self,
        teacher: &B,
        student: &B,
        batch: StepBatch,
        weight: f64,
        geometry_weight: f64,
    ) -> Result<(GradientsParams, LossValues), TrainError> {
        let (out, measured) = self.forward(teacher, student, batch, geometry_weight)?;
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

/// `image` in `dtype` (`None`: as it is, f32).
fn in_dtype(image: Tensor<4>, dtype: Option<FloatDType>) -> Tensor<4> {
    match dtype {
        Some(dtype) => image.cast(dtype),
        None => image,
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
