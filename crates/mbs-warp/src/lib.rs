//! Forward warping of a view by its own disparity (z-buffer splatting), hole
//! masks and mask dilation: the geometric half of novel-view extrapolation
//! (conventions §4, steps 2 and 3). Inpainting the masked pixels is `mbs-infer`'s job.
//!
//! Directions follow conventions §2: warping towards a camera on the right moves a
//! pixel at `x` to `x - d`, towards a camera on the left to `x + d`. The
//! extrapolated views of a pair are the left image warped with
//! [`mbs_core::Side::Left`] (to `-B`) and the right image warped with
//! [`mbs_core::Side::Right`] (to `+2B`), both by their own disparity.

pub mod error;
pub mod extrapolate;
pub mod forward;
pub mod holes;
pub mod morph;

pub use error::WarpError;
pub use extrapolate::{Dilation, WarpedView, extrapolate_view};
pub use forward::{SAME_SURFACE_PX, Warped, forward_warp};
pub use holes::fill_disparity_background;
pub use morph::{EdgeSide, Shape, dilate, dilate_one_side};
