//! Errors of the training library.

use std::path::PathBuf;

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
    /// A training configuration (file, `--set` override) is malformed.
    #[error("configuration: {0}")]
    Config(String),
    /// A data file could not be read or written; the reader's message
    /// already names the file.
    #[error("{0}")]
    Input(String),
    /// A data file (manifest, image, ground truth) could not be used.
    #[error("{path}: {reason}")]
    Data {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A checkpoint could not be written or read.
    #[error("checkpoint {path}: {reason}")]
    Checkpoint {
        /// The checkpoint folder or file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// A device could not be opened or failed while training on it.
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

impl From<mbs_core::FormatError> for TrainError {
    fn from(e: mbs_core::FormatError) -> Self {
        TrainError::Input(e.to_string())
    }
}

impl From<mbs_dataset::DatasetError> for TrainError {
    fn from(e: mbs_dataset::DatasetError) -> Self {
        TrainError::Input(e.to_string())
    }
}

impl From<mbs_viz::VizError> for TrainError {
    fn from(e: mbs_viz::VizError) -> Self {
        TrainError::Input(format!("drawing: {e}"))
    }
}

impl TrainError {
    /// A [`TrainError::Data`] for `path`.
    pub fn data(path: impl Into<PathBuf>, reason: impl ToString) -> Self {
        TrainError::Data {
            path: path.into(),
            reason: reason.to_string(),
        }
    }

    /// A [`TrainError::Weights`] for `path`.
    pub fn weights(path: impl Into<PathBuf>, reason: impl ToString) -> Self {
        TrainError::Weights {
            path: path.into(),
            reason: reason.to_string(),
        }
    }

    /// A [`TrainError::Checkpoint`] for `path`.
    pub fn checkpoint(path: impl Into<PathBuf>, reason: impl ToString) -> Self {
        TrainError::Checkpoint {
            path: path.into(),
            reason: reason.to_string(),
        }
    }
}
