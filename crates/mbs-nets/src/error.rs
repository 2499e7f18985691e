//! Errors of the networks: settings, shapes, weights, checkpoints, devices.

use std::path::PathBuf;

use thiserror::Error;

/// What can go wrong when building, loading or running a network.
#[derive(Debug, Error, PartialEq)]
pub enum NetError {
    /// A setting is out of its valid range.
    #[error("invalid setting `{name}` = {value}: {reason}")]
    InvalidSetting {
        /// Name of the setting (as in the config struct).
        name: &'static str,
        /// The rejected value, printed.
        value: String,
        /// What a valid value looks like.
        reason: String,
    },
    /// Tensors or images handed to a network do not have the expected shapes.
    #[error("shape mismatch: {0}")]
    Shape(String),
    /// A value could not be read back from the device as f32.
    #[error("could not read {0} back from the device as f32")]
    Readback(&'static str),
    /// A network configuration (`--set network.KEY=VALUE`, a checkpoint's
    /// `network` section) is malformed.
    #[error("configuration: {0}")]
    Config(String),
    /// A checkpoint could not be written or read.
    #[error("checkpoint {path}: {reason}")]
    Checkpoint {
        /// The checkpoint folder or file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// A device could not be opened or failed while running on it.
    #[error("device `{name}`: {reason}")]
    Device {
        /// The device as named (`cuda:0`, `vulkan`).
        name: String,
        /// What is missing or went wrong.
        reason: String,
    },
    /// A weights file (an official checkpoint, an export) could not be
    /// read, written or matched to the network.
    #[error("weights {path}: {reason}")]
    Weights {
        /// The weights file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
}

impl NetError {
    /// A [`NetError::Weights`] for `path`.
    pub fn weights(path: impl Into<PathBuf>, reason: impl ToString) -> Self {
        NetError::Weights {
            path: path.into(),
            reason: reason.to_string(),
        }
    }

    /// A [`NetError::Checkpoint`] for `path`.
    pub fn checkpoint(path: impl Into<PathBuf>, reason: impl ToString) -> Self {
        NetError::Checkpoint {
            path: path.into(),
            reason: reason.to_string(),
        }
    }
}
