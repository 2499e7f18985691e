//! One S3 training step: teacher forward (no gradient) on the clean pair,
//! student forward on the augmented pair, loss on clean images, Adam step
//! with gradient clipping, EMA update of the teacher; on one device, or
//! data parallel on several.

use burn::config::Config;
use burn::optim::{GradientsAccumulator, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, FloatDType, Tensor};

use crate::clip::unscale_and_clip;
use crate::data::StepBatch;
use crate::distributed::{Collective, FlatGradients};
use crate::ema::ema_update;
use crate::error::TrainError;
use crate::losses::{LossConfig, LossInputs, LossOutput, S3Loss};
use crate::optimizer::OptimizerConfig;
use crate::precision::{LossScale, Precision, cast_network};
use crate::schedule::{CosineMomentum, OneCycle, OneCycleConfig};
use crate::supervision::{Supervision, measure};
use mbs_nets::NetError;
use mbs_nets::host::{read_all, read_scalar};
use mbs_nets::ranges;
use mbs_nets::{Backbone, predict, predict_sequence};

/// Everything a training run sets besides the network.
#[derive(Config, Debug)]
pub struct TrainerConfig {
    /// Loss weights and ablation switches.
    pub loss: LossConfig,
    /// One-cycle learning rate (its `total_steps` also ends the EMA schedule).
    pub lr: OneCycleConfig,
    /// EMA momentum at step 0; it rises to 1 on a cosine.
    #[config(default = 0.996)]
    pub ema_base: f64,
    /// Share of the run's steps before the geometry term is switched on,
    /// so that the student (and the EMA teacher with it) learns from the
    /// photometric term before a teacher that is still random supervises
    /// it; 0 supervises from the first step (the paper). `None` (the
    /// default) is 0 here; a training run picks it by backbone
    /// ([`crate::RunConfig::backbone_defaults`]).
    #[config(default = "None")]
    pub geometry_start: Option<f64>,
    /// Share of the run's steps over which the geometry term's weight then
    /// rises linearly from 0 to 1; 0 weighs it fully at once (the paper).
    /// `None` as [`TrainerConfig::geometry_start`].
    #[config(default = "None")]
    pub geometry_warmup: Option<f64>,
    /// Update the teacher by EMA; `false` keeps the initial teacher fixed
    /// (paper Table 3, row (D)*).
    #[config(default = true)]
    pub ema: bool,
    /// Limit of the global gradient L2 norm (as PyTorch's `clip_grad_norm_`).
    #[config(default = 1.0)]
    pub grad_clip_norm: f64,
    /// The optimiser.
    #[config(default = "OptimizerConfig::new()")]
    pub optimizer: OptimizerConfig,
    /// Decay `gamma` of the weights of an iterative student's earlier
    /// predictions ([`sequence_weights`]).
    #[config(default = 0.9)]
    pub sequence_gamma: f64,
    /// Supervise only an iterative student's final prediction.
    #[config(default = false)]
    pub final_prediction_only: bool,
    /// An iterative teacher (RAFT-Stereo, IGEV-Stereo) makes its
    /// pseudo-labels with the network's test iterations (`test_iters`);
    /// `false` (the default) uses the training ones, the iterations the
    /// update operator is trained for. From random weights the extra
    /// iterations can diverge (a small IGEV-Stereo's teacher failed while
    /// its student learned: README, "S3 from random weights"). Validation
    /// and inference always use the test iterations.
    #[config(default = false)]
    pub teacher_test_iters: bool,
    /// The format the networks compute in: `f32`, or mixed precision with
    /// `bf16` or `f16` (f32 weights, optimiser and losses; see
    /// [`crate::precision`]).
    #[config(default = "Precision::F32")]
    pub precision: Precision,
    /// The loss scale an f16 run starts at (PyTorch's `GradScaler`
    /// default); steps whose gradients overflow halve it.
    #[config(default = "LossScale::PYTORCH_INITIAL")]
    pub initial_loss_scale: f64,
}

/// The loss weight of each of `n` predictions of an iterative network,
/// first to last: `gamma'^(n - 1 - i)` with `gamma' = gamma^(15 / (n - 1))`,
/// as the official RAFT-Stereo and IGEV-Stereo sequence losses (the
/// adjustment keeps the weights comparable for any iteration count); the
/// final prediction weighs 1. With `final_only`, the earlier ones weigh 0.
pub fn sequence_weights(n: usize, gamma: f64, final_only: bool) -> Vec<f64> {
    if n <= 1 || final_only {
        let mut weights = vec![0.0; n];
        if let Some(last) = weights.last_mut() {
            *last = 1.0;
        }
        return weights;
    }
    let adjusted = gamma.powf(15.0 / (n - 1) as f64);
    (0..n).map(|i| adjusted.powi((n - 1 - i) as i32)).collect()
}

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
    pub terms: LossTerms,
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

/// The unweighted loss terms of a step, read back from the device.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LossTerms {
    /// `mean(A |d_s - r d_t|)`.
    pub geometry: Option<f32>,
    /// `mean(M_s P_s)`.
    pub photometric: Option<f32>,
    /// `L_s`.
    pub smoothness: Option<f32>,
    /// The range term (`None` when its weight is 0).
    pub range: Option<f32>,
    /// The view term (`None` when its weight is 0).
    pub view: Option<f32>,
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
    /// The loss scale of an f16 run (`None` otherwise).
    loss_scale: Option<LossScale>,
    /// Steps before the geometry term is on.
    geometry_start_steps: usize,
    /// Steps of the geometry term's warm-up after that.
    geometry_warmup_steps: usize,
    /// f16 steps skipped in a row for overflowing gradients.
    skipped_in_a_row: usize,
    step: usize,
}

/// f16 steps skipped in a row after which a run counts as diverged: each
/// skip halves the loss scale (down to 1), so by then the gradients
/// overflow at any scale.
pub const MAX_SKIPPED_STEPS: usize = 30;

/// What the student minimises: the S3 loss of its final prediction plus
/// the weighted losses of its earlier ones. Plain settings, shared by the
/// threads of a data-parallel step.
#[derive(Debug, Clone)]
struct Objective {
    loss: S3Loss,
    sequence_gamma: f64,
    final_prediction_only: bool,
    precision: Precision,
    /// The geometry term's weight at the step being taken.
    geometry_weight: f64,
    /// The teacher's pseudo-labels come from its test iterations.
    teacher_test_iters: bool,
}

/// The loss values of a batch (or of a share of one), read back.
#[derive(Debug, Clone, Copy, Default)]
struct LossValues {
    total: f32,
    terms: LossTerms,
    supervision: Supervision,
}

impl TrainerConfig {
    /// Checks the loss, schedule, EMA and clipping settings.
    pub fn validate(&self) -> Result<(), TrainError> {
        self.loss.validate()?;
        self.lr.init()?;
        ranges::unit("ema_base", self.ema_base)?;
        let start = self.geometry_start.unwrap_or(0.0);
        let warmup = self.geometry_warmup.unwrap_or(0.0);
        ranges::unit("geometry_start", start)?;
        ranges::unit("geometry_warmup", warmup)?;
        if start + warmup > 1.0 {
            return Err(TrainError::Config(format!(
                "geometry_start + geometry_warmup is {}: the geometry term would not reach its \
                 full weight within the run (at most 1)",
                start + warmup
            )));
        }
        ranges::unit("sequence_gamma", self.sequence_gamma)?;
        self.optimizer.validate()?;
        ranges::positive("initial_loss_scale", self.initial_loss_scale)?;
        ranges::positive("grad_clip_norm", self.grad_clip_norm)?;
        Ok(())
    }
}

impl Objective {
    /// Teacher and student predictions and the loss on `batch`, on the
    /// student's device (the student's own gradient path when it has one),
    /// the networks in the run's precision and the loss in f32.
    fn forward<B: Backbone>(
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
    fn gradients<B: Backbone>(
        &self,
        teacher: &B,
        student: &B,
        batch: StepBatch,
        weight: f64,
    ) -> Result<(GradientsParams, LossValues), TrainError> {
        let (out, measured) = self.forward(teacher, student, batch)?;
        let read = |term: Option<Tensor<1>>, what| term.map(|t| read_scalar(t, what)).transpose();
        let values = LossValues {
            total: read_scalar(out.total.clone(), "the loss")?,
            terms: LossTerms {
                geometry: read(out.geometry, "the geometry term")?,
                photometric: read(out.photometric, "the photometric term")?,
                smoothness: read(out.smoothness, "the smoothness term")?,
                range: read(out.range, "the range term")?,
                view: read(out.view, "the view term")?,
            },
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
    /// The values, the share's weight and its gradient length as bytes,
    /// for the other ranks ([`Self::decode`]): f64s, each optional one
    /// preceded by 1 (present) or 0.
    fn encode(&self, weight: f64, gradient_length: usize) -> Vec<u8> {
        let s = &self.supervision;
        let optional = [
            self.terms.geometry,
            self.terms.photometric,
            self.terms.smoothness,
            self.terms.range,
            self.terms.view,
            s.student_mask,
            s.teacher_mask,
        ];
        let mut floats = vec![weight, gradient_length as f64, f64::from(self.total)];
        for value in optional {
            floats.push(f64::from(u8::from(value.is_some())));
            floats.push(value.map_or(0.0, f64::from));
        }
        floats.extend(
            [
                s.disparity_min,
                s.disparity_mean,
                s.disparity_max,
                s.outside,
            ]
            .map(f64::from),
        );
        floats.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    /// What [`Self::encode`] wrote: the values, the weight and the gradient
    /// length; `None` for bytes of another length.
    fn decode(bytes: &[u8]) -> Option<(Self, f64, usize)> {
        let floats: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|chunk| f64::from_le_bytes(chunk.try_into().unwrap_or_default()))
            .collect();
        if floats.len() != 21 || bytes.len() != 21 * 8 {
            return None;
        }
        let optional = |i: usize| (floats[3 + 2 * i] == 1.0).then(|| floats[4 + 2 * i] as f32);
        let values = Self {
            total: floats[2] as f32,
            terms: LossTerms {
                geometry: optional(0),
                photometric: optional(1),
                smoothness: optional(2),
                range: optional(3),
                view: optional(4),
            },
            supervision: Supervision {
                student_mask: optional(5),
                teacher_mask: optional(6),
                disparity_min: floats[17] as f32,
                disparity_mean: floats[18] as f32,
                disparity_max: floats[19] as f32,
                outside: floats[20] as f32,
            },
        };
        Some((values, floats[0], floats[1] as usize))
    }

    /// The sum of each share's values times its weight.
    fn weighted_sum(shares: &[(LossValues, f64)]) -> Self {
        let sum = |value: fn(&LossValues) -> Option<f32>| {
            shares
                .iter()
                .map(|(values, weight)| value(values).map(|v| v * *weight as f32))
                .sum::<Option<f32>>()
        };
        Self {
            total: sum(|v| Some(v.total)).unwrap_or_default(),
            terms: LossTerms {
                geometry: sum(|v| v.terms.geometry),
                photometric: sum(|v| v.terms.photometric),
                smoothness: sum(|v| v.terms.smoothness),
                range: sum(|v| v.terms.range),
                view: sum(|v| v.terms.view),
            },
            supervision: Supervision::combine(
                &shares
                    .iter()
                    .map(|(values, weight)| (values.supervision, *weight))
                    .collect::<Vec<_>>(),
            ),
        }
    }
}

impl<B: Backbone> S3Trainer<B> {
    /// A trainer for `student` (on an autodiff device); the teacher starts
    /// as a copy of it without autodiff (`student.valid()`).
    pub fn new(student: B, config: &TrainerConfig) -> Result<Self, TrainError> {
        config.validate()?;
        let loss = S3Loss::new(config.loss.clone())?;
        let lr = config.lr.init()?;
        let optimizer = config.optimizer.init();
        // Rounded at the start and at the end of the warm-up, so that the
        // term reaches its full weight within the run.
        let step_at = |share: f64| (share * config.lr.total_steps as f64).round() as usize;
        let start = config.geometry_start.unwrap_or(0.0);
        let warmup_end = step_at(start + config.geometry_warmup.unwrap_or(0.0));
        Ok(Self {
            teacher: student.valid(),
            student,
            optimizer,
            objective: Objective {
                loss,
                sequence_gamma: config.sequence_gamma,
                final_prediction_only: config.final_prediction_only,
                precision: config.precision,
                geometry_weight: 1.0,
                teacher_test_iters: config.teacher_test_iters,
            },
            lr,
            momentum: CosineMomentum {
                base: config.ema_base,
                total_steps: config.lr.total_steps,
            },
            ema: config.ema,
            grad_clip_norm: config.grad_clip_norm,
            loss_scale: (config.precision == Precision::F16)
                .then(|| LossScale::starting_at(config.initial_loss_scale)),
            geometry_start_steps: step_at(start),
            geometry_warmup_steps: warmup_end - step_at(start),
            skipped_in_a_row: 0,
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
        if let (Some(scale), Some(saved)) = (&mut self.loss_scale, loss_scale) {
            *scale = saved;
        }
    }

    /// The maps of `batch` (predictions and masks) without a gradient step.
    pub fn diagnose(&self, batch: StepBatch) -> Result<Diagnosis, TrainError> {
        let student = self.student.valid();
        let (out, _) = self
            .objective
            .forward(&self.teacher, &student, batch.clone())?;
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
        self.objective.geometry_weight = self.geometry_weight();
        let (grads, values) =
            self.objective
                .gradients(&self.teacher, &self.student, batch, self.scale())?;
        self.apply(grads, values)
    }

    /// Takes one optimisation step on `batch` split across `devices`, data
    /// parallel: each device gets a share of the items (in order, sizes
    /// differing by at most one), a copy of both networks, and computes the
    /// gradient of its share's loss in a thread of its own. The gradients,
    /// each weighted by its share of the items, are summed on the student's
    /// device, where clipping, the optimiser and the EMA teacher update
    /// once, as in [`Self::step`]; the next step copies the updated weights
    /// out again, so every device starts each step from the same weights.
    /// Each share's loss is normalised over its own items, as in PyTorch's
    /// DistributedDataParallel. With one device this is [`Self::step`].
    pub fn step_parallel(
        &mut self,
        batch: StepBatch,
        devices: &[Device],
    ) -> Result<StepReport, TrainError> {
        if devices.len() <= 1 {
            return self.step(batch);
        }
        let items = batch.reference.dims()[0];
        if let Some(message) = unshareable(items, devices.len(), "devices") {
            return Err(TrainError::Config(message));
        }
        let shares = batch.split(devices.len());
        self.objective.geometry_weight = self.geometry_weight();
        let objective = &self.objective;
        let results = std::thread::scope(|scope| {
            let workers: Vec<_> = shares
                .into_iter()
                .zip(devices)
                .map(|(share, device)| {
                    let weight = share.reference.dims()[0] as f64 / items as f64;
                    let scaled = weight * self.scale();
                    let student = self.student.clone().fork(&device.clone().autodiff());
                    let teacher = self.teacher.clone().to_device(device);
                    let share = share.to_device(device);
                    scope.spawn(move || {
                        objective
                            .gradients(&teacher, &student, share, scaled)
                            .map(|(grads, values)| (grads, values, weight, student))
                    })
                })
                .collect();
            workers
                .into_iter()
                .zip(devices)
                .map(|(worker, device)| {
                    worker.join().unwrap_or_else(|_| {
                        Err(NetError::Device {
                            name: format!("{device:?}"),
                            reason: "its share of the step failed (the runtime panicked)".into(),
                        }
                        .into())
                    })
                })
                .collect::<Result<Vec<_>, _>>()
        })?;
        let home = devices[0].clone();
        let mut sum = GradientsAccumulator::<B>::new();
        let mut shares = Vec::with_capacity(results.len());
        for (grads, values, weight, replica) in results {
            sum.accumulate(&self.student, grads.to_device(&home, &replica));
            shares.push((values, weight));
        }
        self.apply(sum.grads(), LossValues::weighted_sum(&shares))
    }

    /// Takes this process's part of one optimisation step of a run spread
    /// over the processes of `collective` (MPI ranks), each holding the
    /// same weights and the same whole `batch`: rank r computes the
    /// gradient of share r of the items (as [`Self::step_parallel`] shares
    /// them among devices, weighted by its share of the items), the ranks
    /// sum their gradients in one all-reduce of a flat buffer, and each
    /// clips, steps the optimiser and updates its teacher identically, so
    /// the weights stay the same everywhere (see
    /// [`crate::distributed::check_same_weights`]). The report is the
    /// whole batch's, on every rank.
    pub fn step_distributed(
        &mut self,
        batch: StepBatch,
        collective: &dyn Collective,
    ) -> Result<StepReport, TrainError> {
        let ranks = collective.size();
        let items = batch.reference.dims()[0];
        if let Some(message) = unshareable(items, ranks, "processes") {
            return Err(TrainError::Distributed(message));
        }
        let share = batch.split(ranks).swap_remove(collective.rank());
        let weight = share.reference.dims()[0] as f64 / items as f64;
        self.objective.geometry_weight = self.geometry_weight();
        let (grads, values) =
            self.objective
                .gradients(&self.teacher, &self.student, share, weight * self.scale())?;
        let mut flat = FlatGradients::gather(&self.student, &grads)?;
        // The shares' loss values, and the gradient lengths, which must
        // agree before the buffers are summed.
        let mine = values.encode(weight, flat.values.len());
        let shares = collective
            .gather(&mine)
            .iter()
            .map(|bytes| LossValues::decode(bytes))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| TrainError::Distributed("a rank sent unreadable loss values".into()))?;
        if let Some(rank) = shares
            .iter()
            .position(|(_, _, len)| *len != flat.values.len())
        {
            return Err(TrainError::Distributed(format!(
                "rank {rank} computed {} gradient values where rank {} computed {}: the \
                 processes do not train the same network",
                shares[rank].2,
                collective.rank(),
                flat.values.len()
            )));
        }
        collective.sum(&mut flat.values);
        let shares: Vec<_> = shares.into_iter().map(|(v, w, _)| (v, w)).collect();
        self.apply(flat.into_grads(), LossValues::weighted_sum(&shares))
    }

    /// The geometry term's weight at the current step: 0 before its
    /// start, then rising linearly from 0 over the warm-up, then 1.
    pub fn geometry_weight(&self) -> f64 {
        let Some(since) = self.step.checked_sub(self.geometry_start_steps) else {
            return 0.0;
        };
        match self.geometry_warmup_steps {
            0 => 1.0,
            steps => (since as f64 / steps as f64).min(1.0),
        }
    }

    /// The loss scale of an f16 run; 1 otherwise.
    fn scale(&self) -> f64 {
        self.loss_scale.map_or(1.0, |s| s.scale)
    }

    /// The loss scale of an f16 run (`None` for f32 and bf16).
    pub fn loss_scale(&self) -> Option<LossScale> {
        self.loss_scale
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
        let loss_scale = self.loss_scale.map(|s| s.scale);
        let grad_norm =
            unscale_and_clip(&self.student, &mut grads, self.grad_clip_norm, self.scale())?;
        let diverged = |what: String| TrainError::Diverged {
            step: self.step + 1,
            what,
        };
        let skipped = match &mut self.loss_scale {
            Some(scale) => {
                scale.update(grad_norm.is_finite());
                !grad_norm.is_finite()
            }
            None if !values.total.is_finite() => {
                return Err(diverged(format!("the loss is {}", values.total)));
            }
            None if !grad_norm.is_finite() => {
                return Err(diverged(format!("the gradient norm is {grad_norm}")));
            }
            None => false,
        };
        self.skipped_in_a_row = if skipped {
            self.skipped_in_a_row + 1
        } else {
            0
        };
        if self.skipped_in_a_row >= MAX_SKIPPED_STEPS {
            return Err(diverged(format!(
                "the f16 gradients overflowed {MAX_SKIPPED_STEPS} steps in a row \
                 (loss scale now {})",
                self.scale()
            )));
        }
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
