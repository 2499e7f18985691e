//! Why an image, a frame list or a source could not be scored. The
//! messages are those `eval` and `benchmark` print, each naming its file.

use std::error::Error;
use std::path::PathBuf;

use mbs_core::FormatError;
use mbs_dataset::DatasetError;

use crate::protocol::ProtocolError;

/// A failure to score an image, or to list what is scored.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// The ground truth has no finite pixel.
    #[error("{}: the ground truth has no valid pixel: nothing to score", .0.display())]
    NoValidPixel(PathBuf),
    /// The predictions folder has no file named after the image.
    #[error("no prediction {name}.pfm, .png or .exr in {}", folder.display())]
    MissingPrediction {
        /// The image's name.
        name: String,
        /// The predictions folder.
        folder: PathBuf,
    },
    /// A pair to predict, and nothing to predict it with.
    #[error("{}: no prediction and no disparity source", .0.display())]
    NoSource(PathBuf),
    /// The protocol scores NOC only and the ground truth has no mask.
    #[error("{}: {error}", gt.display())]
    NeedsMask {
        /// The ground-truth file.
        gt: PathBuf,
        /// The protocol's refusal (part of the message, not a cause).
        error: ProtocolError,
    },
    /// The protocol cannot compare the prediction with the ground truth
    /// (their sizes).
    #[error("{}: {error} (ground truth {})", prediction.display(), gt.display())]
    Rules {
        /// The prediction file (the reference view for a predicted pair).
        prediction: PathBuf,
        /// The ground-truth file.
        gt: PathBuf,
        /// The protocol's refusal (part of the message, not a cause).
        error: ProtocolError,
    },
    /// A source or ground truth could not be listed or read.
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// A prediction could not be read.
    #[error(transparent)]
    Format(#[from] FormatError),
    /// The protocol has no rules for the data.
    #[error(transparent)]
    Protocol(#[from] ProtocolError),
    /// The disparity source failed on a pair.
    #[error(transparent)]
    Predict(Box<dyn Error + Send + Sync>),
    /// A frame list could not be read.
    #[error("reading the frame list {}", path.display())]
    ReadFrameList {
        /// The list.
        path: PathBuf,
        /// Why.
        #[source]
        source: FormatError,
    },
    /// A frame list names no frame.
    #[error("{}: the frame list names no frame", .0.display())]
    EmptyFrameList(PathBuf),
    /// A frame list names frames that are nowhere.
    #[error(
        "{}: {} listed frame(s) not found in {places}: {}",
        list.display(),
        missing.len(),
        missing.join(", ")
    )]
    Unlisted {
        /// The list.
        list: PathBuf,
        /// Where the frames were looked for.
        places: String,
        /// The names not found, in list order.
        missing: Vec<String>,
    },
}
