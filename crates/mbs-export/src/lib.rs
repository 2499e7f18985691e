//! A trained network as a deployable ONNX model: its forward pass captured
//! on burn's graph-capture device, lowered to ONNX operators and written as
//! a protobuf, with the model card that runs it.

pub mod capture;
pub mod check;
pub mod lower;
pub mod model;
pub mod pair;
pub mod proto;
pub mod report;

pub use check::{Agreement, Tolerance};
pub use model::{
    CheckedExportError, Export, ExportError, Exported, export_checked, onnx_model, stereo_card,
};
pub use report::{Probe, Report};
