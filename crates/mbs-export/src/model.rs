//! A network as an ONNX model file's bytes and the model card that runs it.

use mbs_nets::Backbone;
use prost::Message;
use serde_json::json;

use crate::capture::{CaptureError, capture};
use crate::lower::{Boundary, LowerError, OPSETS, lower};
use crate::proto::{ModelProto, OperatorSetIdProto, StringStringEntryProto};

/// The ONNX IR version written: that of ONNX 1.11 to 1.13, whose operator
/// sets are 16 to 18.
pub const IR_VERSION: i64 = 8;
/// The model's inputs, as the card names them.
pub const INPUTS: [&str; 2] = ["left", "right"];
/// The model's output.
pub const OUTPUT: &str = "disparity";

/// Why a network could not be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The forward pass could not be recorded.
    #[error(transparent)]
    Capture(#[from] CaptureError),
    /// The recorded graph has no ONNX form.
    #[error(transparent)]
    Lower(#[from] LowerError),
    /// An operator set outside the supported ones.
    #[error("opset {0} is not supported: choose 16, 17 or 18")]
    Opset(i64),
}

/// What to export: the input size, the operator set and metadata.
pub struct Export<'a> {
    /// Input height, pixels.
    pub height: usize,
    /// Input width, pixels.
    pub width: usize,
    /// ONNX operator set (16 to 18).
    pub opset: i64,
    /// `key`, `value` pairs stored in the model (backbone, source, …).
    pub metadata: &'a [(String, String)],
}

/// `network`'s disparity as an ONNX model (its bytes): inputs `left` and
/// `right`, `[1, 3, H, W]` RGB in `[0, 1]`, output `disparity` `[1, 1, H,
/// W]` in pixels.
pub fn onnx_model<B: Backbone + Clone>(
    network: &B,
    export: &Export,
) -> Result<Vec<u8>, ExportError> {
    if !OPSETS.contains(&export.opset) {
        return Err(ExportError::Opset(export.opset));
    }
    let captured = capture(network, export.height, export.width)?;
    let boundary = Boundary {
        inputs: &INPUTS,
        output: OUTPUT,
    };
    let graph = lower(&captured, &boundary, export.opset)?;
    let metadata_props = export
        .metadata
        .iter()
        .map(|(key, value)| StringStringEntryProto {
            key: key.clone(),
            value: value.clone(),
        })
        .collect();
    let model = ModelProto {
        ir_version: IR_VERSION,
        producer_name: "mbs".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        doc_string: "Stereo disparity exported by mbs-tool export".into(),
        graph: Some(graph),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: export.opset,
        }],
        metadata_props,
    };
    Ok(model.encode_to_vec())
}

/// The model card (JSON) that runs an exported model of `height` x
/// `width`: 8-bit RGB divided by 255, as mbs's own networks read images,
/// and the disparity as it comes out.
pub fn stereo_card(name: &str, notes: &str, height: usize, width: usize) -> serde_json::Value {
    json!({
        "name": name,
        "task": "stereo",
        "notes": notes,
        "inputs": { "left": INPUTS[0], "right": INPUTS[1] },
        "layout": "NCHW",
        "color_order": "RGB",
        "dtype": "float32",
        "scale": 1.0,
        "mean": [0.0, 0.0, 0.0],
        "std": [255.0, 255.0, 255.0],
        "size": { "mode": "fixed", "width": width, "height": height },
        "output": { "name": OUTPUT, "sign": 1 }
    })
}
