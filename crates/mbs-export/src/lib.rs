//! A trained network as a deployable ONNX model: its forward pass captured
//! on burn's graph-capture device, lowered to ONNX operators and written as
//! a protobuf, with the model card that runs it.

pub mod capture;
pub mod lower;
pub mod model;
pub mod proto;

pub use model::{Export, ExportError, onnx_model, stereo_card};
