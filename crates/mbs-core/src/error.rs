//! The error type of file readers and writers: every variant names the file.

use std::path::{Path, PathBuf};

/// Result of a file operation in mbs-core.
pub type Result<T> = std::result::Result<T, FormatError>;

/// A failure to read or write a file, always naming the file.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// The operating system refused an operation (missing file, permissions…).
    #[error("{}: {source}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file exists but its content is not what the format requires.
    #[error("{}: {message}", path.display())]
    Invalid {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong, in words.
        message: String,
    },
    /// The `image` crate failed to decode or encode the file.
    #[error("{}: {source}", path.display())]
    Image {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        source: image::ImageError,
    },
    /// The `exr` crate failed to decode or encode the file.
    #[error("{}: {source}", path.display())]
    Exr {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        source: exr::error::Error,
    },
}

impl FormatError {
    /// An [`FormatError::Invalid`] for `path` with `message`.
    pub fn invalid(path: &Path, message: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    /// An [`FormatError::Io`] for `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// An [`FormatError::Image`] for `path`.
    pub fn image(path: &Path, source: image::ImageError) -> Self {
        Self::Image {
            path: path.to_path_buf(),
            source,
        }
    }

    /// What is wrong, without the file's name (for errors that name the
    /// file themselves).
    pub fn reason(&self) -> String {
        match self {
            Self::Io { source, .. } => source.to_string(),
            Self::Invalid { message, .. } => message.clone(),
            Self::Image { source, .. } => source.to_string(),
            Self::Exr { source, .. } => source.to_string(),
        }
    }

    /// The file this error is about.
    pub fn path(&self) -> &Path {
        match self {
            Self::Io { path, .. }
            | Self::Invalid { path, .. }
            | Self::Image { path, .. }
            | Self::Exr { path, .. } => path,
        }
    }
}
