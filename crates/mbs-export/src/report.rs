//! The deployment report written beside an exported model: what the graph
//! holds, whether its shapes are static, what TensorRT users should check,
//! and how close its values come to half precision's limits on the check
//! pair.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::Path;

use mbs_core::RgbImage;
use mbs_infer::onnx::runtime::{RuntimeOptions, session_from_bytes};
use ort::session::SessionInputValue;
use ort::value::Tensor;
use prost::Message;

use crate::check::Agreement;
use crate::proto::{AttributeProto, FLOAT, GraphProto, ModelProto, NodeProto, ValueInfoProto};

/// Half precision's largest finite value.
pub const F16_MAX: f32 = 65504.0;

/// What the report says.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// The ONNX operator set.
    pub opset: i64,
    /// Nodes of the graph.
    pub nodes: usize,
    /// Nodes by operator.
    pub operators: BTreeMap<String, usize>,
    /// Every input, output and intermediate has a fixed shape and no node
    /// computes a shape at run time.
    pub static_shapes: bool,
    /// Points a TensorRT user should know, one line each.
    pub tensorrt: Vec<String>,
    /// With [`Probe::Every`], the largest magnitude of any intermediate
    /// value on the check pair and the intermediates beyond half
    /// precision's range.
    pub activations: Option<(f32, Vec<String>)>,
    /// The largest correlation-lookup coordinate (the inputs of its
    /// `Floor` nodes) and half precision's step there, pixels of the
    /// lookup's grid; `None` for a network with no lookup.
    pub lookup_f16_step: Option<(f32, f32)>,
    /// The largest disparity on the check pair and half precision's step
    /// there, pixels.
    pub disparity_f16_step: (f32, f32),
    /// The agreement with mbs's own forward pass.
    pub agreement: Agreement,
}

/// Which values the report measures on the check pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Probe {
    /// The disparity and the lookup coordinates: one run.
    Output,
    /// Every intermediate too: one run per [`PROBE_CHUNK`] values (ONNX
    /// Runtime keeps each probed value alive to the end of a run).
    Every,
}

/// Values probed per run with [`Probe::Every`].
pub const PROBE_CHUNK: usize = 64;

/// Reads `model` and probes it on the pair.
pub fn report(
    model: &ModelProto,
    path: &Path,
    pair: (&RgbImage, &RgbImage),
    agreement: Agreement,
    (probe_what, options): (Probe, &RuntimeOptions),
) -> Result<Report, String> {
    let no_graph = GraphProto::default();
    let graph = model.graph.as_ref().unwrap_or(&no_graph);
    let opset = model.opset_import.first().map_or(0, |o| o.version);
    let mut operators = BTreeMap::new();
    for node in &graph.node {
        *operators.entry(node.op_type.clone()).or_insert(0) += 1;
    }
    let static_shapes = all_static(graph) && !operators.contains_key("Shape");
    let lookups: Vec<String> = graph
        .node
        .iter()
        .filter(|n| n.op_type == "Floor")
        .flat_map(|n| n.input.clone())
        .collect();
    // The graph's one output, the disparity.
    let output = graph
        .output
        .first()
        .map(|o| o.name.clone())
        .unwrap_or_default();
    let first: Vec<String> = lookups.iter().cloned().chain([output.clone()]).collect();
    let measured = probe(model, path, pair, options, &first)?;
    let disparity = measured.get(&output).copied().unwrap_or(0.0);
    let lookup = lookups
        .iter()
        .filter_map(|n| measured.get(n))
        .copied()
        .reduce(f32::max);
    let activations = match probe_what {
        Probe::Output => None,
        Probe::Every => Some(activations_of(model, graph, path, pair, options)?),
    };
    Ok(Report {
        opset,
        nodes: graph.node.len(),
        tensorrt: tensorrt_notes(&operators, graph),
        operators,
        static_shapes,
        activations,
        lookup_f16_step: lookup.map(|v| (v, f16_step(v))),
        disparity_f16_step: (disparity, f16_step(disparity)),
        agreement,
    })
}

/// The largest magnitude of any float intermediate of `model` on `pair`
/// and those beyond half precision's range, named with their operator,
/// probed [`PROBE_CHUNK`] at a time.
fn activations_of(
    model: &ModelProto,
    graph: &GraphProto,
    path: &Path,
    pair: (&RgbImage, &RgbImage),
    options: &RuntimeOptions,
) -> Result<(f32, Vec<String>), String> {
    let every: Vec<String> = graph
        .value_info
        .iter()
        .filter(|v| elem_type(v) == Some(FLOAT))
        .map(|v| v.name.clone())
        .collect();
    let mut magnitudes = BTreeMap::new();
    for chunk in every.chunks(PROBE_CHUNK) {
        magnitudes.extend(probe(model, path, pair, options, chunk)?);
    }
    let largest = magnitudes.values().copied().fold(0.0, f32::max);
    let producer: BTreeMap<&str, &str> = graph
        .node
        .iter()
        .flat_map(|n| n.output.iter().map(|o| (o.as_str(), n.op_type.as_str())))
        .collect();
    let beyond = magnitudes
        .iter()
        .filter(|(_, v)| **v > F16_MAX)
        .map(|(name, v)| {
            let op = producer.get(name.as_str()).copied().unwrap_or("?");
            format!("{name} ({op}, {v:.3e})")
        })
        .collect();
    Ok((largest, beyond))
}

/// Whether every typed value has a shape of fixed, positive sides.
fn all_static(graph: &GraphProto) -> bool {
    let typed = graph
        .input
        .iter()
        .chain(&graph.output)
        .chain(&graph.value_info);
    typed.into_iter().all(|value| {
        let shape = value
            .r#type
            .as_ref()
            .and_then(|t| t.tensor_type.as_ref())
            .and_then(|t| t.shape.as_ref());
        shape.is_some_and(|s| s.dim.iter().all(|d| d.dim_value > 0) || s.dim.is_empty())
    })
}

/// The lines a TensorRT user should read.
fn tensorrt_notes(operators: &BTreeMap<String, usize>, graph: &GraphProto) -> Vec<String> {
    let count = |op: &str| operators.get(op).copied().unwrap_or(0);
    let mut notes = vec![format!(
        "GridSample: {} (the correlation lookup is written as GatherElements, {} nodes), so \
         TensorRT's GridSample issues at opset 20 and its missing 5-D grid sampling do not apply",
        count("GridSample"),
        count("GatherElements")
    )];
    let volumetric = graph
        .node
        .iter()
        .filter(|n| n.op_type.starts_with("Conv") && kernel_rank(n) == 3)
        .count();
    if volumetric > 0 {
        notes.push(format!(
            "{volumetric} 3-D convolutions (the cost volume's): supported by TensorRT's \
             IConvolutionLayer on 5-D tensors; check FP16 tactics for them"
        ));
    }
    let edge_pads = graph
        .node
        .iter()
        .filter(|n| n.op_type == "Pad" && is_edge(n))
        .count();
    if edge_pads > 0 {
        notes.push(format!(
            "{edge_pads} edge Pad nodes: the size is not a multiple of 32, so the network pads \
             its input; exporting at a multiple of 32 removes them"
        ));
    }
    notes.push("every Reshape, Expand and Slice takes constant shapes: no dynamic reshape".into());
    notes
}

fn kernel_rank(node: &NodeProto) -> usize {
    node.attribute
        .iter()
        .find(|a| a.name == "kernel_shape")
        .map_or(0, |a| a.ints.len())
}

fn is_edge(node: &NodeProto) -> bool {
    node.attribute
        .iter()
        .any(|a| a.name == "mode" && a.s == b"edge")
}

/// Half precision's spacing at magnitude `value`.
pub fn f16_step(value: f32) -> f32 {
    if value < 6.1e-5 {
        return 2f32.powi(-24);
    }
    2f32.powi(value.log2().floor() as i32 - 10)
}

/// The largest magnitude of each value of `model` named in `watched` on
/// `pair`: a copy of the model whose extra outputs are each value's
/// `ReduceMax` and `ReduceMin`, placed right after the node that makes it,
/// run once.
fn probe(
    model: &ModelProto,
    path: &Path,
    (left, right): (&RgbImage, &RgbImage),
    options: &RuntimeOptions,
    watched: &[String],
) -> Result<BTreeMap<String, f32>, String> {
    let mut model = model.clone();
    let graph = model.graph.as_mut().ok_or("the model has no graph")?;
    let index: BTreeMap<&str, usize> = watched
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    let mut nodes = Vec::with_capacity(graph.node.len() * 3);
    for made in std::mem::take(&mut graph.node) {
        let probed: Vec<(usize, String)> = made
            .output
            .iter()
            .filter_map(|o| index.get(o.as_str()).map(|&i| (i, o.clone())))
            .collect();
        nodes.push(made);
        for (i, name) in probed {
            for reduce in ["ReduceMax", "ReduceMin"] {
                let keep = AttributeProto::int("keepdims", 0);
                let out = format!("probe_{reduce}_{i}");
                nodes.push(node(reduce, vec![name.clone()], &out, vec![keep]));
                graph.output.push(ValueInfoProto::tensor(&out, FLOAT, &[]));
            }
        }
    }
    graph.node = nodes;
    // The graph's two inputs, the left and right views in that order.
    let [Some(left_input), Some(right_input)] =
        [0, 1].map(|i| graph.input.get(i).map(|input| input.name.clone()))
    else {
        return Err("the model does not have two inputs".into());
    };
    let (mut session, _) =
        session_from_bytes(path, &model.encode_to_vec(), options).map_err(|e| e.to_string())?;
    let inputs = [(left_input, left), (right_input, right)]
        .into_iter()
        .map(|(name, image)| {
            let (width, height) = image.dimensions();
            let shape = vec![1i64, 3, i64::from(height), i64::from(width)];
            let tensor = Tensor::from_array((shape, planar(image))).map_err(|e| e.to_string())?;
            Ok((name.into(), SessionInputValue::from(tensor)))
        })
        .collect::<Result<Vec<(std::borrow::Cow<str>, SessionInputValue)>, String>>()?;
    let outputs = session.run(inputs).map_err(|e| e.to_string())?;
    let scalar = |name: String| -> Result<f32, String> {
        let value = outputs
            .get(name.as_str())
            .ok_or("a probe output is missing")?;
        let (_, data) = value
            .try_extract_tensor::<f32>()
            .map_err(|e| e.to_string())?;
        Ok(data.first().copied().unwrap_or(0.0))
    };
    let mut magnitudes = BTreeMap::new();
    for (i, name) in watched.iter().enumerate() {
        let largest = scalar(format!("probe_ReduceMax_{i}"))?;
        let smallest = scalar(format!("probe_ReduceMin_{i}"))?;
        magnitudes.insert(name.clone(), largest.abs().max(smallest.abs()));
    }
    Ok(magnitudes)
}

fn node(
    op_type: &str,
    input: Vec<String>,
    output: &str,
    attribute: Vec<AttributeProto>,
) -> NodeProto {
    NodeProto {
        input,
        output: vec![output.to_string()],
        name: output.to_string(),
        op_type: op_type.to_string(),
        attribute,
    }
}

fn elem_type(value: &ValueInfoProto) -> Option<i32> {
    value
        .r#type
        .as_ref()?
        .tensor_type
        .as_ref()
        .map(|t| t.elem_type)
}

/// `image` as planar RGB in `[0, 1]` (`v / 255`, as mbs reads images).
fn planar(image: &RgbImage) -> Vec<f32> {
    (0..3)
        .flat_map(|c| image.pixels().map(move |p| f32::from(p[c]) / 255.0))
        .collect()
}

impl Report {
    /// The report as Markdown, for people.
    pub fn markdown(&self, title: &str) -> String {
        let mut text = format!("# {title}\n\n");
        let a = &self.agreement;
        let _ = writeln!(
            text,
            "- ONNX opset {}, {} nodes; static shapes: {}",
            self.opset,
            self.nodes,
            if self.static_shapes { "yes" } else { "no" }
        );
        let _ = writeln!(
            text,
            "- agreement with mbs on the check pair: largest {:.2e} px, mean {:.2e} px over {} of {} pixels; \
             mbs {:.2} s, ONNX Runtime {:.2} s (CPU)",
            a.largest, a.mean, a.compared, a.pixels, a.mbs_seconds, a.onnx_seconds
        );
        let (disparity, step) = self.disparity_f16_step;
        let _ = writeln!(
            text,
            "- FP16: the largest disparity on the check pair, {disparity:.1} px, has a \
             half-precision step of {step} px"
        );
        if let Some((coordinate, step)) = self.lookup_f16_step {
            let _ = writeln!(
                text,
                "- FP16: the correlation lookup reaches coordinate {coordinate:.1}, where half \
                 precision resolves its fractional part, which sets the bilinear weights, to {step}"
            );
        }
        match &self.activations {
            Some((largest, beyond)) => {
                let _ = writeln!(
                    text,
                    "- FP16: largest intermediate magnitude {largest:.3e} (half precision reaches \
                     {F16_MAX}); {} intermediates beyond it{}",
                    beyond.len(),
                    if beyond.is_empty() {
                        String::new()
                    } else {
                        format!(": {}", beyond.join(", "))
                    }
                );
            }
            None => text.push_str(
                "- FP16: intermediates not probed (`export --fp16-probe` measures every one)\n",
            ),
        }
        text.push_str("\n## TensorRT\n\n");
        for note in &self.tensorrt {
            let _ = writeln!(text, "- {note}");
        }
        text.push_str("\n## Operators\n\n| operator | nodes |\n| --- | --- |\n");
        for (op, n) in &self.operators {
            let _ = writeln!(text, "| {op} | {n} |");
        }
        text
    }
}
