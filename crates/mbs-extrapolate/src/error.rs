//! The error type of extrapolation: every variant names the file or says
//! which input is at fault.

use std::path::PathBuf;

/// Why a pair could not be extrapolated.
#[derive(Debug, thiserror::Error)]
pub enum ExtrapolateError {
    /// An input or output file could not be read or written.
    #[error(transparent)]
    Format(#[from] mbs_core::FormatError),
    /// A dataset folder or manifest is not as expected.
    #[error(transparent)]
    Dataset(#[from] mbs_dataset::DatasetError),
    /// The warp refused its inputs.
    #[error(transparent)]
    Warp(#[from] mbs_warp::WarpError),
    /// Disparity estimation or inpainting failed.
    #[error(transparent)]
    Infer(#[from] mbs_infer::InferError),
    /// A contact sheet could not be drawn.
    #[error(transparent)]
    Picture(#[from] mbs_viz::VizError),
    /// An input file holds something extrapolation cannot use.
    #[error("{}: {message}", path.display())]
    Input {
        /// The file at fault.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// Every pixel of a new view is masked, so inpainting has nothing to
    /// fill from.
    #[error("{view}: every pixel is masked, nothing is left to inpaint from: {cause}")]
    AllMasked {
        /// The new view's name (`image_1`, `image_4`...).
        view: String,
        /// What masked them: the warp or the dilation.
        cause: String,
    },
    /// A depth map cannot become a virtual rig's disparity (NaN values, a
    /// metric depth of zero, a scaling its kind does not allow).
    #[error("depth map: {0}")]
    Depth(String),
    /// Inpainting one of the new views failed.
    #[error("inpainting {view}: {source}")]
    Inpaint {
        /// The new view's name (`image_1`, `image_4`...).
        view: String,
        /// The inpainter's error.
        source: mbs_infer::inpaint::InpaintError,
    },
}

impl ExtrapolateError {
    /// An [`ExtrapolateError::Input`] about `path`.
    pub fn input(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        ExtrapolateError::Input {
            path: path.into(),
            message: message.into(),
        }
    }
}
