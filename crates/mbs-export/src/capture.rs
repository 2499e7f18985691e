//! A network's forward pass at a fixed size, recorded on burn's
//! graph-capture device instead of run.

use std::collections::HashMap;

use burn::backend::capture::{CaptureBackend, CapturedGraph, TensorId};
use burn::module::{ModuleVisitor, Param};
use burn::tensor::{Bool, Device, Int, Tensor};
use mbs_nets::Backbone;

/// Why a forward pass could not be captured.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    /// A tensor was not on the capture device.
    #[error("{0} is not on the capture device")]
    NotCaptured(String),
    /// burn refused the capture's boundary.
    #[error("the capture failed: {0}")]
    Capture(String),
}

/// A recorded forward pass: the operations, the weights' values and their
/// module paths.
pub struct Captured {
    /// The operations in order, with the weights' values.
    pub graph: CapturedGraph,
    /// Each parameter's module path, by tensor.
    pub parameter_names: HashMap<TensorId, String>,
}

/// Records `network`'s disparity for a pair of `height` x `width` images
/// (`[1, 3, H, W]` in `[0, 1]`, inputs `left` and `right`).
pub fn capture<B: Backbone + Clone>(
    network: &B,
    height: usize,
    width: usize,
) -> Result<Captured, CaptureError> {
    let device = Device::capture();
    let mut outcome = None;
    let graph = device.capture_scope(|scope| {
        let network = network.clone().to_device(&device);
        let mut names = ParameterNames::default();
        network.visit(&mut names);
        let image =
            || Tensor::<4>::zeros([1, 3, height, width], &Device::flex()).to_device(&device);
        let (left, right) = (image(), image());
        let inputs = [id(&left, "left"), id(&right, "right")];
        let disparity = network.disparity(left, right);
        let result = boundary(inputs, id(&disparity, "the disparity"), names);
        let (inputs, outputs) = match &result {
            Ok(found) => (found.inputs.clone(), found.outputs.clone()),
            Err(_) => (Vec::new(), Vec::new()),
        };
        outcome = Some(result);
        scope.complete(inputs, outputs)
    });
    let found = outcome.ok_or_else(|| CaptureError::Capture("the scope did not run".into()))??;
    let graph = graph.map_err(|e| CaptureError::Capture(e.to_string()))?;
    Ok(Captured {
        graph,
        parameter_names: found.parameter_names,
    })
}

/// What a capture scope found: the graph's runtime inputs and outputs and
/// each parameter's module path.
struct Found {
    inputs: Vec<TensorId>,
    outputs: Vec<TensorId>,
    parameter_names: HashMap<TensorId, String>,
}

/// The graph's boundary, or the first tensor that is not on the capture
/// device.
fn boundary(
    inputs: [Result<TensorId, CaptureError>; 2],
    output: Result<TensorId, CaptureError>,
    names: ParameterNames,
) -> Result<Found, CaptureError> {
    if let Some(error) = names.error {
        return Err(error);
    }
    Ok(Found {
        inputs: inputs.into_iter().collect::<Result<_, _>>()?,
        outputs: vec![output?],
        parameter_names: names.names,
    })
}

/// The capture id of `tensor`.
fn id(tensor: &Tensor<4>, what: &str) -> Result<TensorId, CaptureError> {
    tensor
        .clone()
        .try_into_primitive::<CaptureBackend>()
        .map(|t| t.id())
        .map_err(|_| CaptureError::NotCaptured(what.to_string()))
}

/// Collects each parameter's module path.
#[derive(Default)]
struct ParameterNames {
    path: Vec<String>,
    names: HashMap<TensorId, String>,
    error: Option<CaptureError>,
}

impl ParameterNames {
    fn record<T>(&mut self, tensor: Result<T, impl std::fmt::Debug>, id: impl Fn(&T) -> TensorId) {
        match tensor {
            Ok(tensor) => {
                let path = self.path.join(".");
                self.names.entry(id(&tensor)).or_insert(path);
            }
            Err(_) => {
                self.error
                    .get_or_insert(CaptureError::NotCaptured(self.path.join(".")));
            }
        }
    }
}

impl ModuleVisitor for ParameterNames {
    fn enter_module(&mut self, name: &str, _container_type: &str) {
        self.path.push(name.to_string());
    }

    fn exit_module(&mut self, _name: &str, _container_type: &str) {
        self.path.pop();
    }

    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        self.record(param.val().try_into_primitive::<CaptureBackend>(), |t| {
            t.id()
        });
    }

    fn visit_int<const D: usize>(&mut self, param: &Param<Tensor<D, Int>>) {
        self.record(param.val().try_into_primitive::<CaptureBackend>(), |t| {
            t.id()
        });
    }

    fn visit_bool<const D: usize>(&mut self, param: &Param<Tensor<D, Bool>>) {
        self.record(param.val().try_into_primitive::<CaptureBackend>(), |t| {
            t.id()
        });
    }
}
