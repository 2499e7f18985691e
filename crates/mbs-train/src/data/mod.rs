//! The training data pipeline: samples from a manifest, random triplets
//! and crops per batch, decoded on worker threads ahead of the step
//! ([`loader::BatchLoader`]), and the held-out pairs with ground truth that
//! validation scores ([`validation::ValidationSet`]).
//!
//! Every random choice of batch `k` comes from a generator seeded by the
//! run's seed and `k` alone ([`step_rng`]), so a resumed run draws exactly
//! the batches an uninterrupted one would, whatever the thread timing.

pub mod batch;
pub mod loader;
pub mod validation;

use burn::config::Config;
use mbs_dataset::Split;

use crate::error::TrainError;
use mbs_core::limits::{MAX_IMAGE_SIDE, MAX_JOBS};
use mbs_nets::ranges;

pub use batch::StepBatch;
pub use loader::BatchLoader;
pub use mbs_batch::rng::{Stream, step_rng};
pub use mbs_batch::samples::{TrainingSamples, ViewPaths};
pub use mbs_batch::{HostBatch, MAX_BATCH_SIZE, MIN_CROP_SIDE};
use mbs_eval::{Dataset, Protocol};
pub use validation::{ValidationPair, ValidationSet};

/// How batches are drawn and loaded.
#[derive(Config, Debug, PartialEq)]
pub struct DataConfig {
    /// Batch items per step (the paper uses 16).
    #[config(default = 16)]
    pub batch_size: usize,
    /// Height of the random crops (384 pretraining, 256 finetuning).
    #[config(default = 384)]
    pub crop_height: usize,
    /// Width of the random crops (512 in the paper).
    #[config(default = 512)]
    pub crop_width: usize,
    /// Threads that decode and crop batches ahead of the step; 0 takes one
    /// per core, so a GPU machine decodes on all its cores. The batches do
    /// not depend on it.
    #[config(default = 0)]
    pub workers: usize,
    /// Camera pairs `[reference, target]` scored by validation, when the
    /// held-out samples have ground truth for them.
    #[config(default = "vec![[0, 1]]")]
    pub val_pairs: Vec<[usize; 2]>,
    /// Validate on at most this many held-out samples (0 = all).
    #[config(default = 32)]
    pub val_samples: usize,
    /// The split validation scores; `None` takes `val`, or `test` when the
    /// manifest has no `val` sample. `train` suits sets whose only ground
    /// truth is on the training samples (extrapolated KITTI).
    #[config(default = "None")]
    pub val_split: Option<Split>,
    /// The protocol validation scores under: `s3`, the S3 paper's (per
    /// image, ground truth in `(0, 191)`, as `benchmark` scores by
    /// default), so a run's curves are on its published tables' scale; or
    /// `pixels`, mbs's (every valid pixel, pooled, as `eval` scores by
    /// default). The other protocols have no rules for a manifest's pairs.
    #[config(default = "String::from(\"s3\")")]
    pub val_protocol: String,
}

impl DataConfig {
    /// The number of loading threads: `workers`, or one per core for 0.
    pub fn loading_threads(&self) -> usize {
        match self.workers {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        }
    }

    /// The protocol validation scores under ([`DataConfig::val_protocol`]).
    pub fn val_protocol(&self) -> Result<Protocol, TrainError> {
        let protocol: Protocol = self
            .val_protocol
            .parse()
            .map_err(|e| TrainError::Config(format!("data.val_protocol: {e}")))?;
        protocol
            .rules(Dataset::Other)
            .map_err(|e| TrainError::Config(format!("data.val_protocol: {e}")))?;
        Ok(protocol)
    }

    /// Checks the ranges and the validation protocol.
    pub fn validate(&self) -> Result<(), TrainError> {
        self.val_protocol()?;
        let side = (MIN_CROP_SIDE, MAX_IMAGE_SIDE as usize);
        Ok(ranges::integers_in(&[
            ("batch_size", self.batch_size, (1, MAX_BATCH_SIZE)),
            ("crop_height", self.crop_height, side),
            ("crop_width", self.crop_width, side),
            ("workers", self.workers, (0, MAX_JOBS)),
        ])?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_pretraining_settings() {
        let config = DataConfig::new();
        assert_eq!(
            (config.batch_size, config.crop_height, config.crop_width),
            (16, 384, 512)
        );
        assert!(config.validate().is_ok());
        assert!(DataConfig::new().with_batch_size(0).validate().is_err());
    }

    #[test]
    fn validation_scores_under_the_s3_protocol_unless_told_pixels() {
        assert_eq!(DataConfig::new().val_protocol().unwrap(), Protocol::S3);
        let pixels = DataConfig::new().with_val_protocol("pixels".into());
        assert_eq!(pixels.val_protocol().unwrap(), Protocol::Pixels);
        for (name, problem) in [("kitti", "no rules for"), ("evaldisp", "is not a protocol")] {
            let error = DataConfig::new()
                .with_val_protocol(name.into())
                .validate()
                .unwrap_err()
                .to_string();
            assert!(
                error.contains("data.val_protocol") && error.contains(problem),
                "{error}"
            );
        }
    }
}
