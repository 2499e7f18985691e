//! S3 self-supervised multi-baseline stereo training on burn: losses, masks and weight map, EMA teacher, schedules, triplet sampling and backbones.
//!
//! Everything runs on burn's run-time selected device (`Device::flex()` on
//! CPU, `.autodiff()` for training); see `DESIGN.md` for the choice of burn.

pub mod augment;
pub mod backbone;
pub mod clip;
pub mod ema;
pub mod error;
pub mod losses;
pub mod mask;
pub mod mirror;
pub mod sampling;
pub mod schedule;
pub mod step;

#[cfg(test)]
mod test_util;

pub use backbone::{Backbone, CostVolumeNet, CostVolumeNetConfig};
pub use error::TrainError;
pub use losses::{LossConfig, LossInputs, LossOutput, S3Loss};
pub use step::{S3Trainer, StepBatch, StepReport, TrainerConfig};
