//! Errors of the training library.

use thiserror::Error;

/// What can go wrong when configuring or feeding the S3 trainer.
#[derive(Debug, Error, PartialEq)]
pub enum TrainError {
    /// A configuration value is out of its valid range.
    #[error("invalid setting `{name}` = {value}: {reason}")]
    InvalidSetting {
        /// Name of the setting (as in the config struct).
        name: &'static str,
        /// The rejected value, printed.
        value: String,
        /// What a valid value looks like.
        reason: &'static str,
    },
    /// Tensors handed to a loss or a network do not have the expected shapes.
    #[error("shape mismatch: {0}")]
    Shape(String),
    /// A value could not be read back from the device as f32.
    #[error("could not read {0} back from the device as f32")]
    Readback(&'static str),
    /// A rig with fewer than two views cannot give a stereo pair.
    #[error("a multi-baseline sample needs at least 2 views, got {0}")]
    TooFewViews(usize),
}
