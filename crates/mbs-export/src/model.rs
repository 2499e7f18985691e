//! A network as an ONNX model file's bytes and the model card that runs it.

use std::path::Path;

use mbs_core::RgbImage;
use mbs_infer::onnx::ModelCard;
use mbs_infer::onnx::card::{ColorOrder, ElementType, Layout, OutputSpec, SizePolicy, Task};
use mbs_infer::onnx::runtime::RuntimeOptions;
use mbs_infer::onnx::stereo::OnnxStereo;
use mbs_nets::Backbone;
use prost::Message;

use crate::check::{Agreement, CheckError, Tolerance, compare};
use crate::report::{Probe, Report, report};

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
    Ok(model_proto(network, export)?.encode_to_vec())
}

/// The model of [`onnx_model`], before it is encoded.
fn model_proto<B: Backbone + Clone>(
    network: &B,
    export: &Export,
) -> Result<ModelProto, ExportError> {
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
    Ok(model)
}

/// The model card that runs an exported model of `height` x `width`:
/// 8-bit RGB divided by 255, as mbs's own networks read images, and the
/// disparity as it comes out.
pub fn stereo_card(name: &str, notes: &str, height: usize, width: usize) -> ModelCard {
    let inputs = INPUTS.map(|role| (role.to_string(), role.to_string()));
    ModelCard {
        name: name.to_string(),
        task: Task::Stereo,
        notes: notes.to_string(),
        inputs: inputs.into_iter().collect(),
        layout: Layout::Nchw,
        color_order: ColorOrder::Rgb,
        dtype: ElementType::Float32,
        scale: 1.0,
        mean: [0.0; 3],
        std: [255.0; 3],
        size: SizePolicy::Fixed {
            width: width as u32,
            height: height as u32,
        },
        output: OutputSpec {
            name: OUTPUT.to_string(),
            sign: 1.0,
            scale: 1.0,
            channel: 0,
            kind: None,
        },
        mask: None,
    }
}

/// An export that passed its check, ready to write.
pub struct Exported {
    /// The ONNX model's bytes.
    pub model: Vec<u8>,
    /// Its model card.
    pub card: ModelCard,
    /// Its deployment report.
    pub report: Report,
}

/// Why a checked export failed.
#[derive(Debug, thiserror::Error)]
pub enum CheckedExportError {
    /// The export itself failed.
    #[error(transparent)]
    Export(#[from] ExportError),
    /// ONNX Runtime refused the model or its card.
    #[error("ONNX Runtime: {0}")]
    Runtime(String),
    /// The check could not run.
    #[error(transparent)]
    Check(#[from] CheckError),
    /// The model disagrees with mbs beyond the tolerance.
    #[error(
        "the ONNX model disagrees with mbs's own forward pass on the check pair: largest \
         {:.3e} px, mean {:.3e} px, over the tolerance of {:.1e} px largest and {:.1e} px mean",
        .agreement.largest, .agreement.mean, .tolerance.largest, .tolerance.mean
    )]
    Disagrees {
        /// What was measured.
        agreement: Agreement,
        /// What was allowed.
        tolerance: Tolerance,
    },
    /// The report's probe failed.
    #[error("the deployment report: {0}")]
    Report(String),
}

/// Exports `network` as [`onnx_model`] and checks it before anything is
/// written: the model, run through ONNX Runtime with its card exactly as
/// `predict --model --card` runs it, must agree with mbs's own forward
/// pass on `pair` (at the export's size) within `tolerance`; the report
/// probes it on the same pair. `path` is where the model will be written
/// (errors name it). `name` and `notes` go into the card; `probe` says
/// how much of the model the report measures.
pub fn export_checked<B: Backbone + Clone>(
    network: &B,
    export: &Export,
    card: (&str, &str),
    pair: (&RgbImage, &RgbImage),
    path: &Path,
    tolerance: &Tolerance,
    (probe, options): (Probe, &RuntimeOptions),
) -> Result<Exported, CheckedExportError> {
    let proto = model_proto(network, export)?;
    let model = proto.encode_to_vec();
    let card = stereo_card(card.0, card.1, export.height, export.width);
    let onnx = OnnxStereo::from_bytes(path, &model, card.clone(), options)
        .map_err(|e| CheckedExportError::Runtime(e.to_string()))?;
    let agreement = compare(network, &onnx, pair.0, pair.1)?;
    if !agreement.within(tolerance) {
        return Err(CheckedExportError::Disagrees {
            agreement,
            tolerance: *tolerance,
        });
    }
    let report = report(&proto, path, pair, agreement, (probe, options))
        .map_err(CheckedExportError::Report)?;
    Ok(Exported {
        model,
        card,
        report,
    })
}
