//! Opening a run, as named steps (where it trains is checked before, in
//! [`super::Placement`]): its data, the processes' agreement, its first
//! weights, resuming from a checkpoint, and the output folder.

use std::path::Path;
use std::sync::PoisonError;

use burn::module::Module;
use burn::tensor::Device;
use mbs_dataset::Manifest;

use super::logs::truncate_log;
use super::resume::check_resumable;
use super::{
    CONFIG_FILE, Start, TRAIN_LOG, VAL_LOG, WEIGHT_DRAWING, initial_weights, run_identity,
};
use crate::checkpoint::Checkpoint;
use crate::config::RunConfig;
use crate::data::{TrainingSamples, ValidationSet};
use crate::distributed::{Collective, agree};
use crate::error::TrainError;
use crate::step::S3Trainer;
use mbs_core::atomic::write_bytes_atomic;
use mbs_nets::StereoNetwork;

/// The training samples of `manifest` (their files checked) and the
/// held-out pairs validation scores.
pub(super) fn load_data(
    manifest: &Path,
    config: &RunConfig,
) -> Result<(TrainingSamples, ValidationSet), TrainError> {
    let parsed = Manifest::load(manifest)?;
    let crop = (config.data.crop_height, config.data.crop_width);
    let samples = TrainingSamples::from_manifest(manifest, &parsed, crop)?;
    samples.check_files(manifest)?;
    let validation = ValidationSet::from_manifest(
        manifest,
        &parsed,
        &config.data.val_pairs,
        config.data.val_split,
        config.data.val_samples,
    )?;
    Ok((samples, validation))
}

/// Makes the processes agree, before anything is written, on the
/// settings, the manifest, the checkpoint each found (`checkpoint`: its
/// steps) and `--init`.
pub(super) fn agree_on_start(
    processes: &dyn Collective,
    config: &RunConfig,
    manifest: &Path,
    checkpoint: Option<usize>,
    init: Option<&Path>,
) -> Result<(), TrainError> {
    let mut identity = run_identity(config, manifest)?;
    identity["checkpoint"] = checkpoint.into();
    identity["init"] = init.map(|p| p.display().to_string()).into();
    agree(processes, &identity)
}

/// The student the run starts from on `train_device`: fresh weights, drawn
/// on the CPU from the run's seed when `seeded` (a fresh run: a checkpoint
/// has its own) so that a seed gives the same network on every device,
/// then the weights of `init` when given.
pub(super) fn first_student(
    config: &RunConfig,
    train_device: &Device,
    seeded: bool,
    init: Option<&Path>,
) -> Result<StereoNetwork, TrainError> {
    let init_device = Device::flex().autodiff();
    let drawing = WEIGHT_DRAWING
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    if seeded {
        init_device.seed(config.seed);
    }
    let fresh = config.network.init(&init_device)?;
    // Forking while `fresh` still shares the (lazy) parameters makes
    // burn initialise them where they are and copy them over.
    let student = fresh.clone().fork(train_device);
    drop(fresh);
    drop(drawing);
    match init {
        Some(init) => Ok(student.with_state_dict(&initial_weights(init)?, init)?),
        None => Ok(student),
    }
}

/// Puts `checkpoint`'s state into `trainer` (the teacher on `device`, the
/// student on `train_device`), once its settings allow resuming with
/// `config`.
pub(super) fn resume(
    trainer: &mut S3Trainer<StereoNetwork>,
    checkpoint: &Checkpoint,
    config: &RunConfig,
    (device, train_device): (&Device, &Device),
) -> Result<(), TrainError> {
    check_resumable(checkpoint, config)?;
    let networks = checkpoint.networks()?;
    trainer.restore(
        networks.student(train_device)?,
        networks.teacher(device)?,
        checkpoint.optimizer()?,
        checkpoint.state.steps,
        checkpoint.state.loss_scale,
    );
    Ok(())
}

/// Readies `out` for the run's writer: its checkpoints removed when it
/// `restart`s, the logs cut back to a resumed run's step (or emptied for a
/// fresh run), and the configuration written.
pub(super) fn prepare_folder(
    out: &Path,
    config: &RunConfig,
    start: Start,
    restart: bool,
) -> Result<(), TrainError> {
    if restart {
        crate::checkpoint::discard_all(out)?;
    }
    for log in [TRAIN_LOG, VAL_LOG] {
        let path = out.join(log);
        match start {
            Start::Resumed(steps) => truncate_log(&path, steps)?,
            // Emptied through the writer, which refuses a special file.
            Start::Fresh => write_bytes_atomic(&path, b"")?,
        }
    }
    let config_json = serde_json::to_vec_pretty(&config.to_json()?)
        .map_err(|e| TrainError::Config(e.to_string()))?;
    Ok(write_bytes_atomic(&out.join(CONFIG_FILE), &config_json)?)
}
