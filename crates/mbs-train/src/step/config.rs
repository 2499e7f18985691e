//! The trainer's settings: everything a training run sets besides the
//! network, and the weights of an iterative student's predictions.

use burn::config::Config;

use crate::error::TrainError;
use crate::losses::LossConfig;
use crate::optimizer::OptimizerConfig;
use crate::precision::{LossScale, Precision};
use crate::schedule::OneCycleConfig;
use mbs_nets::ranges;

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
    /// Loss weight of each direct estimate an iterative student makes
    /// before its updates (IGEV-Stereo's initial disparity from its
    /// geometry encoding volume), apart from the updates' sequence, as the
    /// official IGEV-Stereo loss weighs it (1). `None` (the default) weighs
    /// it as the first prediction of the sequence (`gamma'^n`, 0.2 at 3
    /// iterations). Measured from random weights on four seeds
    /// (docs/quality.md, "The update that marches, and the initial
    /// disparity's weight"), 1 helped one seed and made another drift:
    /// offered, not the default.
    #[config(default = "None")]
    pub initial_weight: Option<f64>,
    /// An iterative teacher (RAFT-Stereo, IGEV-Stereo) makes its
    /// pseudo-labels with the network's test iterations (`test_iters`);
    /// `false` (the default) uses the training ones, the iterations the
    /// update operator is trained for. From random weights the extra
    /// iterations can diverge (a small IGEV-Stereo's teacher failed while
    /// its student learned: docs/training.md, "S3 from random weights"). Validation
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

/// How an iterative student's predictions are weighted in its loss
/// ([`PredictionWeights::of`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictionWeights {
    /// [`TrainerConfig::sequence_gamma`].
    pub gamma: f64,
    /// [`TrainerConfig::final_prediction_only`].
    pub final_only: bool,
    /// [`TrainerConfig::initial_weight`].
    pub initial_weight: Option<f64>,
}

impl PredictionWeights {
    /// The weight of each of `n` predictions, first to last, whose first
    /// `initial` are direct estimates made before the updates
    /// (`Backbone::initial_estimates`): each of those weighs
    /// `initial_weight`, and the updates' predictions follow
    /// [`sequence_weights`] among themselves, as the official IGEV-Stereo
    /// loss; with `initial_weight` `None` all `n` form one sequence. With
    /// `final_only`, all but the last weigh 0.
    pub fn of(&self, n: usize, initial: usize) -> Vec<f64> {
        match self.initial_weight {
            Some(weight) if !self.final_only && initial < n => {
                let mut weights = vec![weight; initial];
                weights.extend(sequence_weights(n - initial, self.gamma, false));
                weights
            }
            _ => sequence_weights(n, self.gamma, self.final_only),
        }
    }
}

impl TrainerConfig {
    /// How the student's predictions are weighted.
    pub fn prediction_weights(&self) -> PredictionWeights {
        PredictionWeights {
            gamma: self.sequence_gamma,
            final_only: self.final_prediction_only,
            initial_weight: self.initial_weight,
        }
    }

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
        if let Some(weight) = self.initial_weight {
            ranges::non_negative("initial_weight", weight)?;
        }
        self.optimizer.validate()?;
        ranges::positive("initial_loss_scale", self.initial_loss_scale)?;
        ranges::positive("grad_clip_norm", self.grad_clip_norm)?;
        Ok(())
    }
}
