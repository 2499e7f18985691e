//! One S3 training step: teacher forward (no gradient) on the clean pair,
//! student forward on the augmented pair, loss on clean images, Adam step
//! with gradient clipping, EMA update of the teacher. The step's
//! arithmetic on one share of a batch is [`objective`]'s; a step on one
//! device is [`S3Trainer::step`] (here), a step split into shares (over
//! this process's devices, and over processes) is [`shares`]'s, whose
//! gradients meet through a [`GradientReduction`] ([`reduce`]) and whose
//! loss values the ranks exchange as [`wire`] spells them. Which of these
//! a run takes is its placement's choice (`crate::run::Strategy`).

mod config;
mod objective;
mod reduce;
mod shares;
mod wire;

use burn::optim::{GradientsParams, ModuleOptimizer};

use crate::clip::unscale_and_clip;
use crate::data::StepBatch;
use crate::ema::ema_update;
use crate::error::TrainError;
use crate::losses::{S3Loss, Terms};
use crate::precision::{LossScale, LossScaling, Precision};
use crate::schedule::{CosineMomentum, GeometryRamp, OneCycle};
use crate::supervision::Supervision;
use mbs_nets::host::read_all;
use mbs_nets::{Backbone, predict};

pub use config::{PredictionWeights, TrainerConfig, sequence_weights};
use objective::{LossValues, Objective};
pub use reduce::{GradientReduction, HostAllReduce, InProcessSum, LocalGradients, ShareGradients};
pub use shares::Sharing;

/// Why a batch of `items` cannot be shared by `sharers` devices or
/// processes (`what`), if it cannot: each needs at least one item.
fn unshareable(items: usize, sharers: usize, what: &str) -> Option<String> {
    (items < sharers).then(|| {
        format!(
            "a batch of {items} cannot be shared by {sharers} {what}: use a batch size of at \
             least the number of {what}"
        )
    })
}

/// What one step reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    /// Step index (0-based) that was just taken.
    pub step: usize,
    /// Total loss before the update.
    pub loss: f32,
    /// The loss terms before their weights (`None` when switched off).
    pub terms: Terms<f32>,
    /// How much supervision the step had (masks, disparity range).
    pub supervision: Supervision,
    /// Global gradient norm before clipping; not finite when an f16 step's
    /// gradients overflowed and the step was skipped.
    pub grad_norm: f64,
    /// The loss scale the step used (f16 runs only).
    pub loss_scale: Option<f64>,
    /// Learning rate used.
    pub lr: f64,
    /// EMA momentum used (1 when EMA is off).
    pub momentum: f64,
}

/// Maps of one batch for inspection (all `[B, 1, H, W]` row-major), taken
/// without a gradient step.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnosis {
    /// Teacher disparity `d_t` on the clean pair.
    pub teacher_disparity: Vec<f32>,
    /// Student disparity `d_s` on the student's input.
    pub student_disparity: Vec<f32>,
    /// Teacher validity mask `M_t` (0/1), when the geometry term is on.
    pub teacher_mask: Option<Vec<f32>>,
    /// Student validity mask `M_s` (0/1).
    pub student_mask: Option<Vec<f32>>,
}

/// Student, EMA teacher, optimiser and schedules.
pub struct S3Trainer<B: Backbone> {
    student: B,
    teacher: B,
    optimizer: ModuleOptimizer,
    objective: Objective,
    lr: OneCycle,
    momentum: CosineMomentum,
    ema: bool,
    grad_clip_norm: f64,
    /// The loss scaling of an f16 run (`None` otherwise).
    loss_scaling: Option<LossScaling>,
    /// The geometry term's weight, step by step.
    geometry: GeometryRamp,
    step: usize,
}

impl<B: Backbone> S3Trainer<B> {
    /// A trainer for `student` (on an autodiff device); the teacher starts
    /// as a copy of it without autodiff (`student.valid()`).
    pub fn new(student: B, config: &TrainerConfig) -> Result<Self, TrainError> {
        config.validate()?;
        let loss = S3Loss::new(config.loss.clone())?;
        let lr = config.lr.init()?;
        let optimizer = config.optimizer.init();
        Ok(Self {
            teacher: student.valid(),
            student,
            optimizer,
            objective: Objective {
                loss,
                weights: config.prediction_weights(),
                precision: config.precision,
                teacher_test_iters: config.teacher_test_iters,
            },
            lr,
            momentum: CosineMomentum {
                base: config.ema_base,
                total_steps: config.lr.total_steps,
            },
            ema: config.ema,
            grad_clip_norm: config.grad_clip_norm,
            loss_scaling: (config.precision == Precision::F16)
                .then(|| LossScaling::starting_at(config.initial_loss_scale)),
            geometry: GeometryRamp::new(
                config.lr.total_steps,
                config.geometry_start,
                config.geometry_warmup,
            ),
            step: 0,
        })
    }

    /// The student network.
    pub fn student(&self) -> &B {
        &self.student
    }

    /// The teacher network (the one used for inference).
    pub fn teacher(&self) -> &B {
        &self.teacher
    }

    /// Steps taken so far (the index of the next step).
    pub fn steps_taken(&self) -> usize {
        self.step
    }

    /// The optimiser (for checkpoints).
    pub fn optimizer(&self) -> &ModuleOptimizer {
        &self.optimizer
    }

    /// Puts back the state of a checkpoint: both networks, the optimiser
    /// state, the number of steps taken and an f16 run's loss scale (a
    /// checkpoint without one leaves the trainer's).
    pub fn restore(
        &mut self,
        student: B,
        teacher: B,
        optimizer: ModuleOptimizer,
        steps: usize,
        loss_scale: Option<LossScale>,
    ) {
        self.student = student;
        self.teacher = teacher;
        self.optimizer = optimizer;
        self.step = steps;
        if let (Some(scaling), Some(saved)) = (&mut self.loss_scaling, loss_scale) {
            scaling.restore(saved);
        }
    }

    /// The maps of `batch` (predictions and masks) without a gradient step.
    /// The geometry term weighs what the ramp gives it at the current step
    /// ([`Self::geometry_weight`]), deliberately, as the next step would
    /// (before the first step, the ramp's start); the weight only scales
    /// the loss, which is not returned, so the maps do not depend on it.
    pub fn diagnose(&self, batch: StepBatch) -> Result<Diagnosis, TrainError> {
        let student = self.student.valid();
        let geometry_weight = self.geometry_weight();
        let (out, _) =
            self.objective
                .forward(&self.teacher, &student, batch.clone(), geometry_weight)?;
        let teacher = predict(
            &self.teacher,
            batch.reference.clone(),
            batch.teacher_target,
            &batch.teacher_sides,
        );
        let student_disparity = predict(
            &student,
            batch.augmented_reference,
            batch.augmented_target,
            &batch.student_sides,
        );
        Ok(Diagnosis {
            teacher_disparity: read_all(teacher, "the teacher disparity")?,
            student_disparity: read_all(student_disparity, "the student disparity")?,
            teacher_mask: out
                .teacher_mask
                .map(|m| read_all(m, "the teacher mask"))
                .transpose()?,
            student_mask: out
                .student_mask
                .map(|m| read_all(m, "the student mask"))
                .transpose()?,
        })
    }

    /// Takes one optimisation step on `batch` (on the student's device).
    pub fn step(&mut self, batch: StepBatch) -> Result<StepReport, TrainError> {
        let (scale, geometry_weight) = (self.scale(), self.geometry_weight());
        let (grads, values) = self.objective.gradients(
            &self.teacher,
            &self.student,
            batch,
            scale,
            geometry_weight,
        )?;
        self.apply(grads, values)
    }

    /// The geometry term's weight at the current step: 0 before its
    /// start, then rising linearly from 0 over the warm-up, then 1 (see
    /// [`GeometryRamp`]).
    pub fn geometry_weight(&self) -> f64 {
        self.geometry.at(self.step)
    }

    /// The loss scale of an f16 run; 1 otherwise.
    fn scale(&self) -> f64 {
        self.loss_scale().map_or(1.0, |s| s.scale)
    }

    /// The loss scale of an f16 run (`None` for f32 and bf16).
    pub fn loss_scale(&self) -> Option<LossScale> {
        self.loss_scaling.as_ref().map(LossScaling::scale)
    }

    /// Whether the step whose loss is `loss` and gradient norm `grad_norm`
    /// is skipped: an f16 step whose gradients overflowed (its loss
    /// scaling decides, see [`LossScaling::record`]); a run in another
    /// precision cannot skip, so a value that is not finite there has
    /// diverged.
    fn skips(&mut self, loss: f32, grad_norm: f64) -> Result<bool, TrainError> {
        let diverged = |what: String| TrainError::Diverged {
            step: self.step + 1,
            what,
        };
        match &mut self.loss_scaling {
            Some(scaling) => scaling.record(grad_norm).map_err(diverged),
            None if !loss.is_finite() => Err(diverged(format!("the loss is {loss}"))),
            None if !grad_norm.is_finite() => {
                Err(diverged(format!("the gradient norm is {grad_norm}")))
            }
            None => Ok(false),
        }
    }

    /// Clips `grads`, steps the optimiser and updates the teacher. An f16
    /// step whose gradients overflowed changes neither network; it only
    /// lowers the loss scale (its report's `grad_norm` is not finite).
    fn apply(
        &mut self,
        mut grads: GradientsParams,
        values: LossValues,
    ) -> Result<StepReport, TrainError> {
        let lr = self.lr.lr(self.step);
        let loss_scale = self.loss_scale().map(|s| s.scale);
        let grad_norm =
            unscale_and_clip(&self.student, &mut grads, self.grad_clip_norm, self.scale())?;
        let skipped = self.skips(values.total, grad_norm)?;
        if !skipped {
            self.student = self.optimizer.step(lr, self.student.clone(), grads);
        }
        let momentum = if self.ema {
            self.momentum.at(self.step)
        } else {
            1.0
        };
        if self.ema && !skipped {
            self.teacher = ema_update(self.teacher.clone(), &self.student.valid(), momentum)?;
        }
        let report = StepReport {
            step: self.step,
            loss: values.total,
            terms: values.terms,
            supervision: values.supervision,
            grad_norm,
            loss_scale,
            lr,
            momentum,
        };
        self.step += 1;
        Ok(report)
    }
}

#[cfg(test)]
mod tests;
