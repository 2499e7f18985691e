//! The error type of matchers and inpainters.

/// Why a matcher could not run on its input.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InferError {
    /// The two views of a pair differ in size.
    #[error("the left view is {left:?} (width, height) but the right view is {right:?}")]
    SizeMismatch {
        /// Size of the left (reference) view.
        left: (u32, u32),
        /// Size of the right (target) view.
        right: (u32, u32),
    },
    /// The views are empty or smaller than the matcher's window.
    #[error("the views are {size:?} (width, height); {what} needs at least {min:?}")]
    TooSmall {
        /// Size of the views.
        size: (u32, u32),
        /// Smallest size that works.
        min: (u32, u32),
        /// Which setting imposes the minimum.
        what: &'static str,
    },
    /// A setting is out of its range.
    #[error("invalid setting {name} = {value}: {expected}")]
    InvalidConfig {
        /// The setting's name.
        name: &'static str,
        /// The value given, as text.
        value: String,
        /// What is accepted.
        expected: &'static str,
    },
    /// The matcher's map is not a prediction (NaN values, or no finite
    /// value at all).
    #[error("{matcher} gave no usable disparity: {problem} (are its weights broken?)")]
    NoPrediction {
        /// The matcher's name.
        matcher: String,
        /// What is wrong with the map.
        problem: String,
    },
    /// A model backend (ONNX Runtime) failed; the message names the model.
    #[error("{0}")]
    Backend(String),
}

/// Result of a matcher.
pub type Result<T> = std::result::Result<T, InferError>;
