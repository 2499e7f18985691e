//! Finding and loading the ONNX Runtime shared library, and opening model
//! sessions on a device.
//!
//! The library is looked for, in order: an explicit path (`--ort-lib`),
//! `ORT_DYLIB_PATH`, then the project's `.ort/onnxruntime/capi/` (installed by
//! `tools/setup-ort.sh`) in the current folder, the executable's folder or any
//! of their parents. It is loaded once per process with `ort::init_from`;
//! a missing or incompatible library is an [`OnnxError`], never a panic.

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Mutex;

use ort::environment::Environment;
use ort::session::Session;
use ort::session::builder::SessionBuilder;

use super::error::{OnnxError, Result};

/// The environment variable naming the library (the same one `ort` reads).
pub const ORT_DYLIB_ENV: &str = "ORT_DYLIB_PATH";

/// Where the library lies below a project root.
const PROJECT_LIB_DIR: &str = ".ort/onnxruntime/capi";

/// The loaded library and its environment; `None` until the first success.
static LOADED: Mutex<Option<(PathBuf, Environment)>> = Mutex::new(None);

/// Where models run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Device {
    /// ONNX Runtime's CPU execution provider.
    #[default]
    Cpu,
    /// The CUDA execution provider on GPU `N` (needs the `cuda` feature and
    /// the `onnxruntime-gpu` library).
    Cuda(u32),
}

impl fmt::Display for Device {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Device::Cpu => f.write_str("cpu"),
            Device::Cuda(n) => write!(f, "cuda:{n}"),
        }
    }
}

impl FromStr for Device {
    type Err = String;

    /// Parses `cpu`, `cuda` (GPU 0) or `cuda:N`.
    fn from_str(s: &str) -> std::result::Result<Device, String> {
        let usage = || format!("invalid device {s:?}: expected cpu, cuda or cuda:N");
        match s.trim() {
            "cpu" => Ok(Device::Cpu),
            "cuda" => Ok(Device::Cuda(0)),
            other => other
                .strip_prefix("cuda:")
                .and_then(|n| n.parse().ok())
                .map(Device::Cuda)
                .ok_or_else(usage),
        }
    }
}

/// How to open model sessions.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RuntimeOptions {
    /// The ONNX Runtime library; `None` = `ORT_DYLIB_PATH`, then the
    /// project's `.ort/`.
    pub library: Option<PathBuf>,
    /// The execution device.
    pub device: Device,
    /// Run on the CPU when the device cannot be used, instead of failing.
    pub allow_cpu_fallback: bool,
    /// Threads inside one inference (0 = ONNX Runtime's default, one per core).
    pub intra_threads: usize,
}

/// The library to load: `explicit`, else `ORT_DYLIB_PATH`, else the
/// project's `.ort/` found upward from the current folder or the executable.
pub fn find_library(explicit: Option<&Path>) -> Result<PathBuf> {
    if let Some(path) = explicit {
        return existing(path, "--ort-lib");
    }
    if let Some(path) = std::env::var_os(ORT_DYLIB_ENV).filter(|p| !p.is_empty()) {
        return existing(Path::new(&path), ORT_DYLIB_ENV);
    }
    let starts: Vec<PathBuf> = [
        std::env::current_dir().ok(),
        std::env::current_exe()
            .ok()
            .and_then(|e| e.parent().map(Path::to_path_buf)),
    ]
    .into_iter()
    .flatten()
    .collect();
    starts
        .iter()
        .flat_map(|start| start.ancestors())
        .find_map(|dir| project_library(&dir.join(PROJECT_LIB_DIR)))
        .ok_or_else(|| OnnxError::RuntimeNotFound {
            searched: format!(
                "no --ort-lib, {ORT_DYLIB_ENV} unset, no {PROJECT_LIB_DIR}/libonnxruntime.so.* above {}",
                starts
                    .iter()
                    .map(|s| s.display().to_string())
                    .collect::<Vec<_>>()
                    .join(" or ")
            ),
        })
}

fn existing(path: &Path, source: &str) -> Result<PathBuf> {
    if path.is_file() {
        Ok(path.to_path_buf())
    } else {
        Err(OnnxError::RuntimeNotFound {
            searched: format!("{source} = {}: no such file", path.display()),
        })
    }
}

/// The newest `libonnxruntime.so.X.Y.Z` in `dir`, if any.
fn project_library(dir: &Path) -> Option<PathBuf> {
    std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("libonnxruntime.so."))
        })
        .max()
}

/// The process's ONNX Runtime environment, loading the library on first use
/// (see [`find_library`]). Loading a second, different library in the same
/// process is an error.
pub fn environment(library: Option<&Path>) -> Result<Environment> {
    let path = find_library(library)?;
    // A poisoned lock only means another thread panicked while loading;
    // the state it guards is still consistent (set once, after success).
    let mut loaded = LOADED.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((loaded_path, env)) = loaded.as_ref() {
        if same_file(loaded_path, &path) {
            return Ok(env.clone());
        }
        return Err(OnnxError::RuntimeLoad {
            path,
            message: format!(
                "this process already loaded ONNX Runtime from {}",
                loaded_path.display()
            ),
        });
    }
    let load_error = |message: String| OnnxError::RuntimeLoad {
        path: path.clone(),
        message,
    };
    let env = ort::init_from(&path)
        .map_err(|e| load_error(e.to_string()))?
        .with_name("mbs")
        .build()
        .map_err(|e| load_error(e.to_string()))?;
    *loaded = Some((path, env.clone()));
    Ok(env)
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

/// Opens `model` as a session on `options.device`, returning it with the
/// device it actually runs on (the CPU after an allowed fallback).
pub fn open_session(model: &Path, options: &RuntimeOptions) -> Result<(Session, Device)> {
    session_from_bytes(model, &model_bytes(model)?, options)
}

/// Opens the model `bytes` as a session, as [`open_session`]; `model` is
/// the file they are (or will be) kept in, which errors name and beside
/// which external weights are looked for.
pub fn session_from_bytes(
    model: &Path,
    bytes: &[u8],
    options: &RuntimeOptions,
) -> Result<(Session, Device)> {
    let env = environment(options.library.as_deref())?;
    let model_error = |message: String| OnnxError::Model {
        path: model.to_path_buf(),
        message,
    };
    // No spinning: ONNX Runtime's idle workers would otherwise keep the
    // cores busy while mbs pre- and post-processes between runs.
    let mut builder = Session::builder(&env)
        .and_then(|b| b.with_intra_op_spinning(false).map_err(Into::into))
        .map_err(|e| model_error(e.to_string()))?;
    if options.intra_threads > 0 {
        builder = builder
            .with_intra_threads(options.intra_threads)
            .map_err(|e| model_error(e.to_string()))?;
    }
    let (mut builder, device) = match options.device {
        Device::Cpu => (builder, Device::Cpu),
        Device::Cuda(n) => match with_cuda(builder, n) {
            Ok(builder) => (builder, Device::Cuda(n)),
            Err(failure) if !options.allow_cpu_fallback => {
                let (_, message) = *failure;
                return Err(OnnxError::Device {
                    device: options.device.to_string(),
                    message: format!("{message}; pass --allow-cpu-fallback to run on the CPU"),
                });
            }
            Err(failure) => (failure.0, Device::Cpu),
        },
    };
    // Weights kept in files beside the model are looked for in its folder.
    if let Some(folder) = model.parent().and_then(Path::to_str) {
        builder = builder
            .with_config_entry(EXTERNAL_DATA_FOLDER, folder)
            .map_err(|e| model_error(e.to_string()))?;
    }
    let session = builder
        .commit_from_memory(bytes)
        .map_err(|e| model_error(e.to_string()))?;
    Ok((session, device))
}

/// ONNX Runtime's session setting for the folder of the files holding a
/// model's external weights, when the model is given as bytes.
const EXTERNAL_DATA_FOLDER: &str = "session.model_external_initializers_file_folder_path";

/// The whole of the model file `model`, read through a handle opened
/// without blocking and checked to be a regular file: a FIFO, a socket or
/// a folder is named at once (ONNX Runtime, reading the path itself, would
/// block on a FIFO, also on one swapped in after a check), and ONNX
/// Runtime is given these very bytes.
fn model_bytes(model: &Path) -> Result<Vec<u8>> {
    mbs_core::regular::read_bytes(model).map_err(|e| OnnxError::Model {
        path: model.to_path_buf(),
        message: match e {
            mbs_core::FormatError::Io { source, .. }
                if source.kind() == std::io::ErrorKind::NotFound =>
            {
                "no such file".to_string()
            }
            e => e.reason(),
        },
    })
}

/// Registers the CUDA execution provider on GPU `n`; on failure gives the
/// builder back (for a CPU fallback) with the reason, boxed (the builder is
/// large).
#[cfg(feature = "cuda")]
fn with_cuda(
    builder: SessionBuilder,
    n: u32,
) -> std::result::Result<SessionBuilder, Box<(SessionBuilder, String)>> {
    let Ok(device_id) = i32::try_from(n) else {
        return Err(Box::new((
            builder,
            format!("GPU index {n} is out of range"),
        )));
    };
    let cuda = ort::ep::CUDA::default()
        .with_device_id(device_id)
        .build()
        .error_on_failure();
    builder.with_execution_providers([cuda]).map_err(|e| {
        let message = format!(
            "the CUDA execution provider did not register ({e}); it needs the onnxruntime-gpu library (tools/setup-ort.sh --gpu), CUDA 13 and cuDNN 9"
        );
        Box::new((e.recover(), message))
    })
}

/// Without the `cuda` feature there is no CUDA provider to register.
#[cfg(not(feature = "cuda"))]
fn with_cuda(
    builder: SessionBuilder,
    _n: u32,
) -> std::result::Result<SessionBuilder, Box<(SessionBuilder, String)>> {
    Err(Box::new((
        builder,
        "this build of mbs has no CUDA support (rebuild with `--features cuda`)".into(),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_parse() {
        assert_eq!("cpu".parse(), Ok(Device::Cpu));
        assert_eq!("cuda".parse(), Ok(Device::Cuda(0)));
        assert_eq!("cuda:3".parse(), Ok(Device::Cuda(3)));
        assert!("gpu".parse::<Device>().is_err());
        assert!("cuda:x".parse::<Device>().is_err());
        assert_eq!(Device::Cuda(1).to_string(), "cuda:1");
    }

    #[test]
    fn a_missing_explicit_library_is_named() {
        let err = find_library(Some(Path::new("/no/such/libonnxruntime.so"))).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("/no/such/libonnxruntime.so"), "{text}");
        assert!(text.contains("tools/setup-ort.sh"), "{text}");
    }

    #[test]
    fn project_libraries_are_found_by_name() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(project_library(dir.path()), None);
        std::fs::write(dir.path().join("libonnxruntime_providers_shared.so"), b"").unwrap();
        std::fs::write(dir.path().join("libonnxruntime.so.1.31.1"), b"").unwrap();
        assert_eq!(
            project_library(dir.path()),
            Some(dir.path().join("libonnxruntime.so.1.31.1"))
        );
    }

    /// A FIFO, a socket, a device or a folder given as the model is named
    /// at once, before ONNX Runtime is looked for: mbs reads the model
    /// through a handle opened without blocking and gives ONNX Runtime
    /// the bytes (it used to open the path again itself, and a FIFO
    /// swapped in between blocked it for ever).
    #[cfg(unix)]
    #[test]
    fn special_files_as_the_model_are_named_without_blocking() {
        use mbs_test_support::special::special_files;
        let dir = tempfile::tempdir().unwrap();
        for special in special_files(dir.path(), "onnx") {
            let path = special.path.clone();
            let (done, outcome) = std::sync::mpsc::channel();
            std::thread::spawn(move || {
                let result = open_session(&path, &RuntimeOptions::default());
                done.send(result.err().map(|e| e.to_string()))
            });
            let err = outcome
                .recv_timeout(std::time::Duration::from_secs(10))
                .unwrap_or_else(|_| panic!("opening {} blocked", special.path.display()))
                .expect("refused");
            assert!(special.is_refused_in(&err), "{err}");
        }
        let missing = dir.path().join("none.onnx");
        let err = model_bytes(&missing).unwrap_err().to_string();
        assert!(
            err.contains("none.onnx") && err.contains("no such file"),
            "{err}"
        );
    }
}
