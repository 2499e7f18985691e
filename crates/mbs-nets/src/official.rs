//! The official implementations' weights in and out: state dicts read from
//! PyTorch `.pth` files or safetensors (with or without DataParallel's
//! `module.` prefix) load into the burn modules, and a module exports to
//! safetensors under the official keys, so the official PyTorch code loads
//! it with `load_state_dict(strict=True)`.
//!
//! A network's burn parameter paths differ from the official keys only
//! where Rust needs names for PyTorch's `nn.Sequential` indices
//! ([`OfficialLayout::official_key`]); the official state dicts also hold
//! copies (`norm3` beside `downsample.1`) and batch-norm counters, which
//! export writes and import ignores.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use burn::module::{Module, ModuleMapper, ModuleVisitor, Param};
use burn::tensor::{Tensor, TensorData};
use mbs_core::atomic::write_bytes_atomic;
use safetensors::{Dtype, SafeTensors};

use crate::error::NetError;

/// A network whose parameters are those of an official implementation.
pub trait OfficialLayout: Module {
    /// The official state-dict key of the parameter at burn path `path`
    /// (dot-separated field names and vector indices).
    fn official_key(path: &str) -> String;
}

/// One tensor of a state dict, as f32.
#[derive(Debug, Clone, PartialEq)]
pub struct StateTensor {
    /// Its shape.
    pub shape: Vec<usize>,
    /// Its values, row-major.
    pub values: Vec<f32>,
}

/// A state dict: official key to tensor (float tensors only; integer
/// buffers such as `num_batches_tracked` are dropped on reading).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StateDict {
    /// The tensors by key.
    pub tensors: BTreeMap<String, StateTensor>,
}

/// The prefix `nn.DataParallel` adds to every key.
const DATA_PARALLEL_PREFIX: &str = "module.";

impl StateDict {
    /// Reads a `.pth`/`.pt` (PyTorch) or `.safetensors` file; the format
    /// is chosen by the extension. A `module.` prefix on every key is
    /// removed.
    pub fn read(path: &Path) -> Result<Self, NetError> {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let mut dict = match extension.as_str() {
            "safetensors" => Self::read_safetensors(path)?,
            "pth" | "pt" | "ckpt" | "bin" => Self::read_pytorch(path)?,
            _ => {
                return Err(NetError::weights(
                    path,
                    "unknown format: expected a .pth, .pt or .safetensors file",
                ));
            }
        };
        if dict.tensors.is_empty() {
            return Err(NetError::weights(path, "holds no float tensors"));
        }
        if let Some((key, count)) = dict.first_non_finite() {
            return Err(NetError::weights(
                path,
                format!(
                    "tensor {key} holds {count} non-finite values (NaN or infinite) of {}; \
                     these weights cannot predict",
                    dict.tensors[&key].values.len()
                ),
            ));
        }
        if dict
            .tensors
            .keys()
            .all(|k| k.starts_with(DATA_PARALLEL_PREFIX))
        {
            dict.tensors = std::mem::take(&mut dict.tensors)
                .into_iter()
                .map(|(k, t)| (k[DATA_PARALLEL_PREFIX.len()..].to_string(), t))
                .collect();
        }
        Ok(dict)
    }

    /// The first tensor (in key order) holding a NaN or an infinity, with
    /// how many it holds.
    pub fn first_non_finite(&self) -> Option<(String, usize)> {
        self.tensors.iter().find_map(|(key, tensor)| {
            let count = tensor.values.iter().filter(|v| !v.is_finite()).count();
            (count > 0).then(|| (key.clone(), count))
        })
    }

    fn read_safetensors(path: &Path) -> Result<Self, NetError> {
        let bytes =
            mbs_core::regular::read_bytes(path).map_err(|e| NetError::weights(path, e.reason()))?;
        let file = SafeTensors::deserialize(&bytes)
            .map_err(|e| NetError::weights(path, format!("not a safetensors file: {e}")))?;
        let mut tensors = BTreeMap::new();
        for (key, view) in file.tensors() {
            let values = match view.dtype() {
                Dtype::F32 => floats(view.data(), 4, |b| {
                    f32::from_le_bytes([b[0], b[1], b[2], b[3]])
                }),
                Dtype::F64 => floats(view.data(), 8, |b| {
                    f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32
                }),
                Dtype::F16 => floats(view.data(), 2, |b| {
                    half::f16::from_le_bytes([b[0], b[1]]).to_f32()
                }),
                Dtype::BF16 => floats(view.data(), 2, |b| {
                    half::bf16::from_le_bytes([b[0], b[1]]).to_f32()
                }),
                _ => continue,
            };
            tensors.insert(
                key,
                StateTensor {
                    shape: view.shape().to_vec(),
                    values,
                },
            );
        }
        Ok(StateDict { tensors })
    }

    fn read_pytorch(path: &Path) -> Result<Self, NetError> {
        use burn::store::pytorch_reader::{DType, PytorchReader};
        // A FIFO or a folder is named here: the reader would block on one.
        mbs_core::regular::open_regular(path).map_err(|e| NetError::weights(path, e.reason()))?;
        let reader = PytorchReader::new(path)
            .map_err(|e| NetError::weights(path, format!("not a PyTorch state dict: {e}")))?;
        let mut tensors = BTreeMap::new();
        for (key, tensor) in reader.into_tensors() {
            let (width, decode): (usize, fn(&[u8]) -> f32) = match tensor.dtype() {
                DType::F32 => (4, |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                DType::F64 => (8, |b| {
                    f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32
                }),
                DType::F16 => (2, |b| half::f16::from_le_bytes([b[0], b[1]]).to_f32()),
                DType::BF16 => (2, |b| half::bf16::from_le_bytes([b[0], b[1]]).to_f32()),
                _ => continue,
            };
            let bytes = tensor
                .read()
                .map_err(|e| NetError::weights(path, format!("tensor {key}: {e}")))?;
            tensors.insert(
                key,
                StateTensor {
                    shape: tensor.shape().to_vec(),
                    values: floats(&bytes, width, decode),
                },
            );
        }
        Ok(StateDict { tensors })
    }

    /// Writes the dict to `path` as safetensors (f32), with `counters`
    /// (keys of int64 zero scalars such as batch-norm's
    /// `num_batches_tracked`) beside it; through a temporary file renamed
    /// when complete.
    pub fn write_safetensors(&self, path: &Path, counters: &[String]) -> Result<(), NetError> {
        let zero = 0i64.to_le_bytes();
        let mut views = Vec::with_capacity(self.tensors.len() + counters.len());
        let bytes: Vec<(&String, Vec<u8>, &[usize])> = self
            .tensors
            .iter()
            .map(|(k, t)| {
                let data = t.values.iter().flat_map(|v| v.to_le_bytes()).collect();
                (k, data, t.shape.as_slice())
            })
            .collect();
        for (key, data, shape) in &bytes {
            let view = safetensors::tensor::TensorView::new(Dtype::F32, shape.to_vec(), data)
                .map_err(|e| NetError::weights(path, e))?;
            views.push(((*key).clone(), view));
        }
        for key in counters {
            let view = safetensors::tensor::TensorView::new(Dtype::I64, vec![], &zero)
                .map_err(|e| NetError::weights(path, e))?;
            views.push((key.clone(), view));
        }
        let metadata = Some(std::collections::HashMap::from([(
            "format".to_string(),
            "pt".to_string(),
        )]));
        let bytes =
            safetensors::serialize(views, metadata).map_err(|e| NetError::weights(path, e))?;
        write_bytes_atomic(path, &bytes).map_err(|e| NetError::weights(path, e))
    }
}

fn floats(bytes: &[u8], width: usize, decode: fn(&[u8]) -> f32) -> Vec<f32> {
    bytes.chunks_exact(width).map(decode).collect()
}

/// The official state dict of `module`: every parameter under its
/// official key, plus the copies the official modules register twice
/// (`norm3` beside `downsample.1`). Returns the dict and the batch-norm
/// counter keys (`num_batches_tracked`) an export writes beside it.
pub fn export_state_dict<M: OfficialLayout>(module: &M) -> (StateDict, Vec<String>) {
    let mut collector = Collector {
        path: Vec::new(),
        key: M::official_key,
        dict: StateDict::default(),
    };
    module.visit(&mut collector);
    let mut dict = collector.dict;
    let copies: Vec<(String, StateTensor)> = dict
        .tensors
        .iter()
        .filter(|(k, _)| k.contains(".downsample.1."))
        .map(|(k, t)| (k.replace(".downsample.1.", ".norm3."), t.clone()))
        .collect();
    dict.tensors.extend(copies);
    let counters = dict
        .tensors
        .keys()
        .filter_map(|k| k.strip_suffix("running_mean"))
        .map(|prefix| format!("{prefix}num_batches_tracked"))
        .collect();
    (dict, counters)
}

/// `module` with every parameter replaced by the tensor of `dict` under its
/// official key. Every parameter must be found with its shape and every
/// float tensor of the dict must be used (copies excepted); otherwise the
/// error lists the missing, mis-shaped and unexpected keys.
pub fn load_state_dict<M: OfficialLayout>(
    module: M,
    dict: &StateDict,
    source: &Path,
) -> Result<M, NetError> {
    let mut loader = Loader {
        path: Vec::new(),
        key: M::official_key,
        dict,
        used: BTreeSet::new(),
        missing: Vec::new(),
        misshaped: Vec::new(),
    };
    let module = module.map(&mut loader);
    let unexpected: Vec<String> = dict
        .tensors
        .keys()
        .filter(|k| !loader.used.contains(*k) && !is_copy(k, &loader.used))
        .cloned()
        .collect();
    if loader.missing.is_empty() && loader.misshaped.is_empty() && unexpected.is_empty() {
        return Ok(module);
    }
    let mut problems = Vec::new();
    for (what, keys) in [
        ("missing", &loader.missing),
        ("with the wrong shape", &loader.misshaped),
        ("unexpected", &unexpected),
    ] {
        if !keys.is_empty() {
            problems.push(format!("{} keys {what}: {}", keys.len(), listing(keys)));
        }
    }
    Err(NetError::weights(
        source,
        format!(
            "does not match the network ({}); check the backbone and its network.* settings",
            problems.join("; ")
        ),
    ))
}

/// A key the official modules register twice (`norm3` of a residual block
/// is also `downsample.1`), whose original was loaded.
fn is_copy(key: &str, used: &BTreeSet<String>) -> bool {
    key.contains(".norm3.") && used.contains(&key.replace(".norm3.", ".downsample.1."))
}

/// The first few keys, then how many more.
fn listing(keys: &[String]) -> String {
    const SHOWN: usize = 8;
    let mut text = keys
        .iter()
        .take(SHOWN)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    if keys.len() > SHOWN {
        text.push_str(&format!(" and {} more", keys.len() - SHOWN));
    }
    text
}

/// The first parameter of `module` (in the order of burn paths)
/// holding a NaN or an infinity, with how many it holds. Reads every
/// parameter to the host.
pub fn first_non_finite_parameter<M: Module>(module: &M) -> Option<(String, usize)> {
    let mut collector = Collector {
        path: Vec::new(),
        key: |path| path.to_string(),
        dict: StateDict::default(),
    };
    module.visit(&mut collector);
    collector.dict.first_non_finite()
}

struct Collector {
    path: Vec<String>,
    key: fn(&str) -> String,
    dict: StateDict,
}

impl ModuleVisitor for Collector {
    fn enter_module(&mut self, name: &str, _container_type: &str) {
        self.path.push(name.to_string());
    }

    fn exit_module(&mut self, _name: &str, _container_type: &str) {
        self.path.pop();
    }

    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let value = param.val();
        let shape = value.dims().to_vec();
        let values = value
            .into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .unwrap_or_default();
        self.dict.tensors.insert(
            (self.key)(&self.path.join(".")),
            StateTensor { shape, values },
        );
    }
}

struct Loader<'a> {
    path: Vec<String>,
    key: fn(&str) -> String,
    dict: &'a StateDict,
    used: BTreeSet<String>,
    missing: Vec<String>,
    misshaped: Vec<String>,
}

impl ModuleMapper for Loader<'_> {
    fn enter_module(&mut self, name: &str, _container_type: &str) {
        self.path.push(name.to_string());
    }

    fn exit_module(&mut self, _name: &str, _container_type: &str) {
        self.path.pop();
    }

    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let key = (self.key)(&self.path.join("."));
        let Some(found) = self.dict.tensors.get(&key) else {
            self.missing.push(key);
            return param;
        };
        let shape = param.val().dims();
        if found.shape != shape {
            self.misshaped.push(format!(
                "{key} (file {:?}, network {:?})",
                found.shape, shape
            ));
            return param;
        }
        self.used.insert(key);
        let values = found.values.clone();
        param.map(|old| {
            let new = Tensor::from_data(TensorData::new(values, shape), &old.device());
            if old.is_require_grad() {
                new.require_grad()
            } else {
                new
            }
        })
    }
}
