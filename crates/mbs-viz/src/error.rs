//! The error type of the drawing functions.

/// A picture that cannot be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum VizError {
    /// The inputs do not make a picture (sizes disagree, nothing to draw).
    #[error("{0}")]
    Input(String),
    /// The chart library failed while drawing.
    #[error("drawing failed: {0}")]
    Draw(String),
    /// The picture could not be written.
    #[error(transparent)]
    Write(#[from] mbs_core::FormatError),
}
