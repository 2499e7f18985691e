//! Errors of the host batches.

use std::path::PathBuf;

use thiserror::Error;

/// What can go wrong when drawing and decoding a batch.
#[derive(Debug, Error, PartialEq)]
pub enum BatchError {
    /// A rig with fewer than two views cannot give a stereo pair.
    #[error("a multi-baseline sample needs at least 2 views, got {0}")]
    TooFewViews(usize),
    /// A data file could not be read; the reader's message names the file.
    #[error("{0}")]
    Input(String),
    /// A data file (manifest, image) could not be used.
    #[error("{path}: {reason}")]
    Data {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
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
}

impl BatchError {
    /// A [`BatchError::Data`] for `path`.
    pub fn data(path: impl Into<PathBuf>, reason: impl ToString) -> Self {
        BatchError::Data {
            path: path.into(),
            reason: reason.to_string(),
        }
    }
}

impl From<mbs_core::FormatError> for BatchError {
    fn from(e: mbs_core::FormatError) -> Self {
        BatchError::Input(e.to_string())
    }
}

impl From<mbs_dataset::DatasetError> for BatchError {
    fn from(e: mbs_dataset::DatasetError) -> Self {
        BatchError::Input(e.to_string())
    }
}
