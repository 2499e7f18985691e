//! Two views into four (conventions §4): a rectified pair is extrapolated to a
//! view one baseline left of its left view and one right of its right view
//! by forward warping each view by its own disparity, masking what no pixel
//! reached, and inpainting it. The result is a four-camera multi-baseline
//! set with a manifest, the training data of S3.
//!
//! ```no_run
//! use mbs_extrapolate::{DisparitySource, Extrapolator};
//! use mbs_infer::inpaint::BackgroundFill;
//! use mbs_warp::Dilation;
//!
//! # fn main() -> Result<(), mbs_extrapolate::ExtrapolateError> {
//! let left = mbs_core::formats::rgb::read_rgb("left.png".as_ref())?;
//! let right = mbs_core::formats::rgb::read_rgb("right.png".as_ref())?;
//! let extrapolator = Extrapolator::new(Dilation::None, Box::new(BackgroundFill::default()));
//! let source = DisparitySource::builtin(0);
//! let disparities = source.disparities(&left, &right)?;
//! let views = extrapolator.extrapolate(&left, &right, &disparities)?;
//! # let _ = views.image_1;
//! # Ok(())
//! # }
//! ```

pub mod disparity;
pub mod error;
pub mod evaluation;
pub mod frame;
pub mod manifest;
pub mod mono;
pub mod photo_set;
pub mod pipeline;

pub use disparity::{Disparities, DisparitySource, load_disparity};
pub use error::ExtrapolateError;
pub use frame::{Frame, kitti_frames, pair_frame};
pub use manifest::{SetKind, ViewFiles, four_view_manifest, views_manifest};
pub use pipeline::{Extrapolator, NewView, NewViews};
