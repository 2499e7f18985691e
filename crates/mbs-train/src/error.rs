//! Errors of the training library.

use std::path::PathBuf;

use mbs_nets::NetError;
use thiserror::Error;

/// What can go wrong when configuring or feeding the S3 trainer.
#[derive(Debug, Error, PartialEq)]
pub enum TrainError {
    /// Tensors handed to a loss or a network do not have the expected shapes.
    #[error("shape mismatch: {0}")]
    Shape(String),
    /// A training configuration (file, `--set` override) is malformed.
    #[error("configuration: {0}")]
    Config(String),
    /// The processes of a distributed run disagree (settings, files,
    /// weights) or cannot share a step.
    #[error("{0}")]
    Distributed(String),
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
    /// The loss, the gradients or the weights stopped being finite; the
    /// step was not taken (or its weights not saved), so the run keeps those
    /// of the step before.
    #[error(
        "training diverged at step {step}: {what}. The weights of the steps before are kept \
         (the run's newest checkpoint); lower the learning rate (--lr) or check the data, \
         and start again (--restart)"
    )]
    Diverged {
        /// The step, numbered from 1 as in `train.jsonl`.
        step: usize,
        /// What stopped being finite.
        what: String,
    },
    /// The training samples or a batch could not be drawn or decoded (a
    /// rig of one camera, an unreadable manifest or image, an augmentation
    /// setting out of range); the message names the file or the setting.
    #[error(transparent)]
    Batch(#[from] mbs_batch::BatchError),
    /// A network could not be built, loaded or run, a checkpoint written or
    /// read, or a device used.
    #[error(transparent)]
    Network(#[from] NetError),
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

    /// A checkpoint error ([`NetError::Checkpoint`]) for `path`.
    pub fn checkpoint(path: impl Into<PathBuf>, reason: impl ToString) -> Self {
        NetError::checkpoint(path, reason).into()
    }
}
