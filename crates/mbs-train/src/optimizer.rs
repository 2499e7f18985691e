//! The optimiser of a run: Adam as the paper (its epsilon PyTorch's 1e-8,
//! not burn's 1e-5), or AdamW with decoupled weight decay as the official
//! RAFT-Stereo and IGEV-Stereo training scripts use (`wdecay` 1e-5).

use burn::config::Config;
use burn::optim::decay::WeightDecayConfig;
use burn::optim::{AdamConfig, AdamWConfig, ModuleOptimizer};
use serde::{Deserialize, Serialize};

use crate::error::TrainError;
use mbs_nets::ranges;

/// Adam or AdamW.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OptimizerKind {
    /// Adam; a weight decay is added to the gradient (L2), as `torch.optim.Adam`.
    Adam,
    /// AdamW: the weight decay shrinks the weights directly (decoupled).
    Adamw,
}

/// Settings of the optimiser.
#[derive(Config, Debug, PartialEq)]
pub struct OptimizerConfig {
    /// Adam (the paper) or AdamW (the official supervised training scripts).
    #[config(default = "OptimizerKind::Adam")]
    pub kind: OptimizerKind,
    /// Adam's epsilon: PyTorch's default, which the paper's code inherits.
    #[config(default = 1e-8)]
    pub epsilon: f64,
    /// Weight decay (0: none; the official AdamW scripts use 1e-5).
    #[config(default = 0.0)]
    pub weight_decay: f64,
}

impl OptimizerConfig {
    /// Checks epsilon and the weight decay.
    pub fn validate(&self) -> Result<(), TrainError> {
        ranges::positive("optimizer.epsilon", self.epsilon)?;
        ranges::non_negative("optimizer.weight_decay", self.weight_decay)?;
        Ok(())
    }

    /// A fresh optimiser.
    pub fn init(&self) -> ModuleOptimizer {
        let epsilon = self.epsilon as f32;
        match self.kind {
            OptimizerKind::Adam => AdamConfig::new()
                .with_epsilon(epsilon)
                .with_weight_decay(
                    (self.weight_decay > 0.0)
                        .then(|| WeightDecayConfig::new(self.weight_decay as f32)),
                )
                .init(),
            OptimizerKind::Adamw => AdamWConfig::new()
                .with_epsilon(epsilon)
                .with_weight_decay(self.weight_decay as f32)
                .init(),
        }
    }
}
