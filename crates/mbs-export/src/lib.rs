//! A trained network as a deployable ONNX model: its forward pass captured
//! on burn's graph-capture device, lowered to ONNX operators and written as
//! a protobuf.

pub mod capture;
pub mod proto;
