//! The checkpoints of a training run as files: `<run>/checkpoints/step-NNNNNNN/`
//! holds `state.json` (format, steps taken, the run's whole configuration,
//! and the trainer's own state) and the networks as burnpack files. This
//! module owns the layout and reads what inference needs, a checkpoint's
//! networks with their `network` configuration; `mbs-train` writes
//! checkpoints and reads the rest of their state.

use std::fs;
use std::path::{Path, PathBuf};

use burn::module::Module;
use burn::store::{BurnpackStore, ModuleSnapshot};
use burn::tensor::{Bytes, Device};
use serde::Deserialize;
use serde_json::Value;

use crate::error::NetError;
use crate::network::{NetworkConfig, StereoNetwork};
use crate::official::first_non_finite_parameter;

/// `format` of `state.json`.
pub const FORMAT: &str = "mbs-checkpoint/1";
/// Folder of a run's checkpoints.
pub const CHECKPOINTS_DIR: &str = "checkpoints";
/// A checkpoint's state file.
pub const STATE_FILE: &str = "state.json";
/// A checkpoint's student network.
pub const STUDENT_FILE: &str = "student.bpk";
/// A checkpoint's teacher network (the one inference uses).
pub const TEACHER_FILE: &str = "teacher.bpk";

/// The checkpoint folder name for `steps` taken.
pub fn folder_name(steps: usize) -> String {
    format!("step-{steps:07}")
}

/// Completed checkpoints (folders with a state file) under a run's
/// checkpoint folder `root`, oldest first, with their steps.
pub fn completed(root: &Path) -> Result<Vec<(usize, PathBuf)>, NetError> {
    let entries = match fs::read_dir(root) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(NetError::checkpoint(root, e)),
    };
    let mut found: Vec<(usize, PathBuf)> = entries
        .filter_map(Result::ok)
        .filter_map(|entry| {
            let name = entry.file_name().into_string().ok()?;
            let steps = name.strip_prefix("step-")?.parse().ok()?;
            let path = entry.path();
            path.join(STATE_FILE).is_file().then_some((steps, path))
        })
        .collect();
    found.sort();
    Ok(found)
}

/// The newest completed checkpoint folder of the run folder `run`, if any.
pub fn latest(run: &Path) -> Result<Option<PathBuf>, NetError> {
    Ok(completed(&run.join(CHECKPOINTS_DIR))?
        .pop()
        .map(|(_, dir)| dir))
}

/// The checkpoint folder `path` names: itself when it holds a state file,
/// else the newest checkpoint of the run folder `path`.
pub fn locate(path: &Path) -> Result<PathBuf, NetError> {
    if path.join(STATE_FILE).is_file() {
        return Ok(path.to_path_buf());
    }
    match latest(path)? {
        Some(dir) => Ok(dir),
        None => Err(NetError::checkpoint(
            path,
            "neither a checkpoint folder (no state.json) nor a training run with checkpoints/",
        )),
    }
}

/// Reads the state file of the checkpoint folder `dir` as `T` (any part
/// of it), checking its format.
pub fn read_state<T: for<'de> Deserialize<'de>>(dir: &Path) -> Result<T, NetError> {
    #[derive(Deserialize)]
    struct Format {
        format: String,
    }
    let path = dir.join(STATE_FILE);
    let text =
        mbs_core::regular::read_text(&path).map_err(|e| NetError::checkpoint(&path, e.reason()))?;
    let not_state =
        |e: serde_json::Error| NetError::checkpoint(&path, format!("not a checkpoint state: {e}"));
    let Format { format } = serde_json::from_str(&text).map_err(not_state)?;
    if format != FORMAT {
        return Err(NetError::checkpoint(
            &path,
            format!("format `{format}`, expected `{FORMAT}`"),
        ));
    }
    serde_json::from_str(&text).map_err(not_state)
}

/// Loads `module`'s weights from the burnpack file `path`.
pub fn load_module<M: Module>(mut module: M, path: &Path) -> Result<M, NetError> {
    let bytes =
        mbs_core::regular::read_bytes(path).map_err(|e| NetError::checkpoint(path, e.reason()))?;
    let mut store = BurnpackStore::from_bytes(Some(Bytes::from_bytes_vec(bytes)));
    module
        .load_from(&mut store)
        .map_err(|e| NetError::checkpoint(path, e))?;
    if let Some((name, count)) = first_non_finite_parameter(&module) {
        return Err(NetError::checkpoint(
            path,
            format!("parameter {name} holds {count} non-finite values (NaN or infinite)"),
        ));
    }
    Ok(module)
}

/// A checkpoint's networks, as inference sees them.
#[derive(Debug, Clone)]
pub struct TrainedNetworks {
    /// The checkpoint folder.
    pub dir: PathBuf,
    /// Optimiser steps taken.
    pub steps: usize,
    /// The networks' configuration.
    pub network: NetworkConfig,
}

impl TrainedNetworks {
    /// Opens a checkpoint folder, or the newest checkpoint of a run folder.
    pub fn open(path: &Path) -> Result<Self, NetError> {
        #[derive(Deserialize)]
        struct State {
            steps: usize,
            config: Value,
        }
        let dir = locate(path)?;
        let state: State = read_state(&dir)?;
        let section = state.config.get("network").ok_or_else(|| {
            NetError::checkpoint(dir.join(STATE_FILE), "the configuration has no `network`")
        })?;
        let network = NetworkConfig::from_json(section)
            .map_err(|e| NetError::checkpoint(dir.join(STATE_FILE), e))?;
        Ok(Self {
            dir,
            steps: state.steps,
            network,
        })
    }

    /// The files this checkpoint is read from.
    pub fn files(&self) -> [PathBuf; 3] {
        [STATE_FILE, TEACHER_FILE, STUDENT_FILE].map(|name| self.dir.join(name))
    }

    /// The files a command reads from `path` (a checkpoint or run folder,
    /// through its newest checkpoint's files; a weights file itself), so
    /// that no output replaces one; a folder that holds no checkpoint
    /// gives itself (the command reports it when it opens it).
    pub fn files_read_from(path: &Path) -> Vec<PathBuf> {
        match path.is_dir() {
            true => {
                Self::open(path).map_or_else(|_| vec![path.to_path_buf()], |n| n.files().into())
            }
            false => vec![path.to_path_buf()],
        }
    }

    /// The teacher (the network used for inference) on `device`.
    pub fn teacher(&self, device: &Device) -> Result<StereoNetwork, NetError> {
        load_module(self.network.init(device)?, &self.dir.join(TEACHER_FILE))
    }

    /// The student on `device`.
    pub fn student(&self, device: &Device) -> Result<StereoNetwork, NetError> {
        load_module(self.network.init(device)?, &self.dir.join(STUDENT_FILE))
    }
}
