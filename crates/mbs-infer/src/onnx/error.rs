//! The error type of ONNX model loading and inference.

use std::path::PathBuf;

/// Why an ONNX model could not be loaded or run. Each variant names the file
/// (library, card or model) and says what to do.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OnnxError {
    /// No ONNX Runtime library was found.
    #[error(
        "ONNX Runtime not found ({searched}); run tools/setup-ort.sh, or give --ort-lib PATH, or set ORT_DYLIB_PATH"
    )]
    RuntimeNotFound {
        /// Where the library was looked for.
        searched: String,
    },
    /// The library exists but could not be loaded (not a library, wrong
    /// version, or another one was loaded before).
    #[error("{path}: cannot load ONNX Runtime: {message}")]
    RuntimeLoad {
        /// The library file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A model card could not be read or is inconsistent.
    #[error("model card {card}: {message}")]
    Card {
        /// The card's name or file.
        card: String,
        /// What is wrong with it.
        message: String,
    },
    /// The model file could not be loaded.
    #[error("{path}: cannot load the ONNX model: {message}")]
    Model {
        /// The model file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The model's declared inputs or outputs disagree with its card.
    #[error("{path}: the model does not match card {card}: {problem}")]
    CardMismatch {
        /// The model file.
        path: PathBuf,
        /// The card's name.
        card: String,
        /// The first disagreement found.
        problem: String,
    },
    /// The execution device was asked for but cannot be used.
    #[error("device {device}: {message}")]
    Device {
        /// The device as given (`cpu`, `cuda:0`).
        device: String,
        /// Why it cannot be used and what to do.
        message: String,
    },
    /// Running the model failed, or its output had an unexpected shape.
    #[error("{path}: inference failed: {message}")]
    Run {
        /// The model file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

/// Result of the ONNX backends.
pub type Result<T> = std::result::Result<T, OnnxError>;
