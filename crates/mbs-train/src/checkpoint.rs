//! Checkpoints of a run, written and resumed: `<run>/checkpoints/step-NNNNNNN/`
//! (the layout of [`mbs_nets::checkpoint`]) holds the student, the teacher
//! and the optimiser state (burnpack files, which keep the parameter ids the
//! optimiser state is keyed by) and `state.json` (format, steps taken, the
//! full configuration, the random state and an f16 run's loss scale).
//!
//! A checkpoint is written into a temporary `step-NNNNNNN.PID-N.partial/`
//! and renamed when complete, so a crash never leaves a folder that looks
//! finished; the next save removes what a killed run left.
//!
//! The random state is the run's seed and the number of steps taken: every
//! random choice of step `k` comes from a generator seeded by both
//! ([`crate::data::step_rng`]), so nothing else needs saving.

use std::fs;
use std::path::{Path, PathBuf};

use crate::config::RunConfig;
use crate::error::TrainError;
use crate::precision::LossScale;
use crate::step::S3Trainer;
use burn::module::Module;
use burn::optim::ModuleOptimizer;
use burn::store::{BurnpackStore, ModuleSnapshot};
use burn::tensor::Bytes;
use mbs_core::atomic::partial_path;
use mbs_nets::Backbone;
use mbs_nets::checkpoint::{
    CHECKPOINTS_DIR, FORMAT, STATE_FILE, STUDENT_FILE, TEACHER_FILE, TrainedNetworks, completed,
    folder_name, latest, locate, read_state,
};
use mbs_nets::official::first_non_finite_parameter;
use serde::{Deserialize, Serialize};
use serde_json::Value;

const OPTIMIZER_FILE: &str = "optimizer.bpk";

/// `state.json` of a checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckpointState {
    /// Always [`FORMAT`].
    pub format: String,
    /// Optimiser steps taken.
    pub steps: usize,
    /// The run's configuration, complete.
    pub config: Value,
    /// The random state.
    pub rng: RngState,
    /// The loss scale of an f16 run (absent otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loss_scale: Option<LossScale>,
}

/// Everything the run's random choices depend on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RngState {
    /// The run's seed.
    pub seed: u64,
    /// The next step's index: its batch and augmentation generators are
    /// ChaCha8 seeded with `seed`, on stream `2 step` and `2 step + 1`.
    pub next_step: usize,
}

/// Folder, under a run's `checkpoints/`, of the checkpoint of its best
/// validation so far ([`save_best`]); pruning never removes it.
pub const BEST_DIR: &str = "best";

/// Writes a checkpoint of a run's `trainer` into `run/checkpoints/` and
/// keeps the newest `keep` of them; returns its folder.
pub fn save<B: Backbone>(
    run: &Path,
    trainer: &S3Trainer<B>,
    config: &RunConfig,
    keep: usize,
) -> Result<PathBuf, TrainError> {
    let root = run.join(CHECKPOINTS_DIR);
    let done = root.join(folder_name(trainer.steps_taken()));
    write(&done, trainer, config)?;
    mbs_core::atomic::remove_stale_partials(&root)
        .map_err(|e| TrainError::checkpoint(e.path(), e.to_string()))?;
    prune(&root, keep)?;
    Ok(done)
}

/// Writes a checkpoint of `trainer` into `run/checkpoints/best/` (see
/// [`BEST_DIR`]), replacing the one there: the run's best validation so
/// far. A checkpoint like the others (`predict --checkpoint
/// RUN/checkpoints/best`, `export RUN/checkpoints/best`), which resuming
/// and pruning, reading only `step-N` folders, leave alone.
pub fn save_best<B: Backbone>(
    run: &Path,
    trainer: &S3Trainer<B>,
    config: &RunConfig,
) -> Result<PathBuf, TrainError> {
    let done = run.join(CHECKPOINTS_DIR).join(BEST_DIR);
    write(&done, trainer, config)?;
    Ok(done)
}

/// The steps of the run folder `run`'s best checkpoint, if it has one.
pub fn best_steps(run: &Path) -> Option<usize> {
    let dir = run.join(CHECKPOINTS_DIR).join(BEST_DIR);
    read_state::<CheckpointState>(&dir).ok().map(|s| s.steps)
}

/// Writes `trainer`'s checkpoint into the folder `done` through a
/// temporary `.partial` folder renamed when complete.
fn write<B: Backbone>(
    done: &Path,
    trainer: &S3Trainer<B>,
    config: &RunConfig,
) -> Result<(), TrainError> {
    let steps = trainer.steps_taken();
    for (which, network) in [
        ("student", trainer.student()),
        ("teacher", trainer.teacher()),
    ] {
        if let Some((name, count)) = first_non_finite_parameter(network) {
            return Err(TrainError::Diverged {
                step: steps,
                what: format!("the {which}'s {name} holds {count} non-finite values"),
            });
        }
    }
    let partial = partial_path(done);
    let io = |path: &Path, e: std::io::Error| TrainError::checkpoint(path, e);
    fs::create_dir_all(&partial).map_err(|e| io(&partial, e))?;
    write_module(&partial.join(STUDENT_FILE), trainer.student())?;
    write_module(&partial.join(TEACHER_FILE), trainer.teacher())?;
    let optimizer_bytes = trainer
        .optimizer()
        .into_bytes()
        .map_err(|e| TrainError::checkpoint(&partial, format!("optimizer state: {e}")))?;
    write_file(&partial.join(OPTIMIZER_FILE), &optimizer_bytes)?;
    let state = CheckpointState {
        format: FORMAT.into(),
        steps,
        config: config.to_json()?,
        rng: RngState {
            seed: config.seed,
            next_step: steps,
        },
        loss_scale: trainer.loss_scale(),
    };
    let json = serde_json::to_vec_pretty(&state).map_err(|e| io(&partial, e.into()))?;
    write_file(&partial.join(STATE_FILE), &json)?;
    if done.exists() {
        fs::remove_dir_all(done).map_err(|e| io(done, e))?;
    }
    fs::rename(&partial, done).map_err(|e| io(done, e))
}

/// Writes one file of a checkpoint; it sits in the `.partial` folder, whose
/// rename is what makes the checkpoint complete.
fn write_file(path: &Path, bytes: &[u8]) -> Result<(), TrainError> {
    fs::write(path, bytes).map_err(|e| TrainError::checkpoint(path, e))
}

fn write_module<M: Module>(path: &Path, module: &M) -> Result<(), TrainError> {
    let mut store = BurnpackStore::from_bytes(None);
    module
        .save_into(&mut store)
        .map_err(|e| TrainError::checkpoint(path, e))?;
    let bytes = store
        .get_bytes()
        .map_err(|e| TrainError::checkpoint(path, e))?;
    write_file(path, &bytes)
}

fn prune(root: &Path, keep: usize) -> Result<(), TrainError> {
    let found = completed(root)?;
    let excess = found.len().saturating_sub(keep.max(1));
    for (_, path) in &found[..excess] {
        fs::remove_dir_all(path).map_err(|e| TrainError::checkpoint(path, e))?;
    }
    Ok(())
}

/// A checkpoint on disk.
#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    /// Its folder.
    pub dir: PathBuf,
    /// Its `state.json`.
    pub state: CheckpointState,
}

/// Removes the completed checkpoints of the run folder `run` (a run
/// started again from fresh weights), its best one too; anything else in
/// its checkpoints folder is left where it is.
pub fn discard_all(run: &Path) -> Result<(), TrainError> {
    for (_, path) in completed(&run.join(CHECKPOINTS_DIR))? {
        fs::remove_dir_all(&path).map_err(|e| TrainError::checkpoint(&path, e))?;
    }
    discard_best(run)
}

/// Removes the best checkpoint of the run folder `run`, if it has one.
pub fn discard_best(run: &Path) -> Result<(), TrainError> {
    let best = run.join(CHECKPOINTS_DIR).join(BEST_DIR);
    if best.join(STATE_FILE).is_file() {
        fs::remove_dir_all(&best).map_err(|e| TrainError::checkpoint(&best, e))?;
    }
    Ok(())
}

impl Checkpoint {
    /// The newest completed checkpoint of the run folder `run`, if any.
    pub fn latest(run: &Path) -> Result<Option<Checkpoint>, TrainError> {
        match latest(run)? {
            Some(dir) => Checkpoint::open(&dir).map(Some),
            None => Ok(None),
        }
    }

    /// Opens a checkpoint: a checkpoint folder, or a run folder (its newest
    /// checkpoint).
    pub fn open(path: &Path) -> Result<Checkpoint, TrainError> {
        let dir = locate(path)?;
        let state = read_state(&dir)?;
        Ok(Checkpoint { dir, state })
    }

    /// The configuration the checkpoint was trained with.
    pub fn config(&self) -> Result<RunConfig, TrainError> {
        RunConfig::from_document(&self.state.config)
            .map_err(|e| TrainError::checkpoint(self.dir.join(STATE_FILE), e))
    }

    /// The checkpoint's teacher and student, with the network settings of
    /// its (checked) configuration.
    pub fn networks(&self) -> Result<TrainedNetworks, TrainError> {
        Ok(TrainedNetworks {
            dir: self.dir.clone(),
            steps: self.state.steps,
            network: self.config()?.network,
        })
    }

    /// The Adam state.
    pub fn optimizer(&self) -> Result<ModuleOptimizer, TrainError> {
        let path = self.dir.join(OPTIMIZER_FILE);
        let bytes = mbs_core::regular::read_bytes(&path)
            .map_err(|e| TrainError::checkpoint(&path, e.reason()))?;
        self.config()?
            .trainer
            .optimizer
            .init()
            .from_bytes(Bytes::from_bytes_vec(bytes))
            .map_err(|e| TrainError::checkpoint(&path, e))
    }
}
