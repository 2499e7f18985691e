//! Stereo matching and inpainting behind traits, with built-in defaults:
//! a semi-global matcher ([`Sgm`]), a block-matching baseline
//! ([`BlockMatcher`]) and background-side inpainting
//! ([`inpaint::BackgroundFill`]); with the default `onnx` feature, ONNX
//! networks through ONNX Runtime ([`onnx::OnnxStereo`],
//! [`onnx::OnnxInpainter`]).
//!
//! Matchers follow conventions §2: they take a rectified pair whose target (right)
//! camera lies right of the reference (left) one and return a non-negative
//! disparity on the reference grid, `+inf` where there is none. The
//! right-view disparity comes from mirroring
//! ([`StereoMatcher::predict_right`]).

pub mod block;
pub mod depth;
pub mod error;
pub mod inpaint;
pub mod matcher;
#[cfg(feature = "onnx")]
pub mod onnx;
pub mod postprocess;
pub mod sgm;

pub use block::BlockMatcher;
pub use depth::{DepthEstimator, DepthKind, DepthMap};
pub use error::InferError;
pub use matcher::{Disparity, StereoMatcher};
pub use sgm::{MAX_ESTIMATED_DISPARITY, Sgm, SgmConfig, SgmPaths, estimate_max_disparity};
