//! Errors of dataset loading and scanning; each names the file or folder.

use std::path::PathBuf;

/// A failure to read, parse or write a dataset description.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A file or folder could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A manifest is not valid JSON or does not fit the manifest model.
    #[error("{}: {message}", path.display())]
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A folder does not have the expected dataset layout.
    #[error("{}: {message}", path.display())]
    Layout {
        /// The folder concerned.
        path: PathBuf,
        /// What is wrong, and what was expected.
        message: String,
    },
    /// Writing a file failed.
    #[error(transparent)]
    Format(#[from] mbs_core::FormatError),
}
