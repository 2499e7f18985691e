//! ONNX models through ONNX Runtime (`ort`, library loaded at run time):
//! [`OnnxStereo`] implements [`StereoMatcher`](crate::StereoMatcher),
//! [`OnnxInpainter`] implements [`Inpainter`](crate::inpaint::Inpainter)
//! and [`OnnxDepth`] maps one image's depth.
//!
//! - [`runtime`]: finding and loading the library (`--ort-lib`,
//!   `ORT_DYLIB_PATH`, the project's `.ort/` from `tools/setup-ort.sh`) and
//!   opening sessions on a [`Device`] (CPU, or CUDA with the `cuda` feature);
//! - [`card`]: [`ModelCard`]s saying how to feed a model (built-in: LaMa,
//!   MI-GAN, CREStereo, HITNet, RAFT-Stereo, IGEV/MonSter, FastDepth);
//! - [`tensor`]: images to tensors and back (padding, layout, normalisation);
//! - [`model`]: a session checked against its card at load;
//! - [`resize`]: bilinear resizing of disparity maps for fixed-size models.

pub mod card;
pub mod depth;
pub mod error;
pub mod inpaint;
pub mod model;
pub mod resize;
pub mod runtime;
pub mod stereo;
pub mod tensor;

pub use card::ModelCard;
pub use depth::OnnxDepth;
pub use error::OnnxError;
pub use inpaint::OnnxInpainter;
pub use runtime::{Device, RuntimeOptions};
pub use stereo::OnnxStereo;
