//! A whole training run in an output folder: data loading ahead of the
//! step, S3 steps, loss logs (`train.jsonl`), periodic validation
//! (`val.jsonl`), checkpoints and resumption.
//!
//! ```text
//! <out>/config.json         the run's complete configuration
//! <out>/train.jsonl         loss terms, LR, momentum, samples/s every `log_every` steps
//! <out>/val.jsonl           EPE and Out-x over ALL/NOC/OCC every `val_every` steps
//! <out>/loss.png, val.png   the curves of both logs
//! <out>/visuals/step-N/     contact sheets of the first validation pairs
//! <out>/tensorboard/        TensorBoard events: every logged number, the sheets
//! <out>/checkpoints/step-N/ student, teacher, optimiser, state.json
//! ```
//!
//! Opening a folder that has a checkpoint resumes from it: logs are cut
//! back to the checkpoint's step and batch `k` is drawn exactly as in an
//! uninterrupted run (see [`crate::data::step_rng`]).

use std::fs;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use burn::module::Module;
use burn::tensor::Device;
use mbs_batch::share;
use mbs_core::atomic::write_bytes_atomic;
use mbs_core::{FloatImage, RgbImage};
use mbs_dataset::Manifest;

use crate::checkpoint::{self, Checkpoint};
use crate::config::RunConfig;
use crate::data::StepBatch;
use crate::data::validation::{ValidationMetrics, ValidationPair};
use crate::data::{BatchLoader, TrainingSamples, ValidationSet};
use crate::distributed::{Collective, agree, check_same_weights};
use crate::error::TrainError;
use crate::precision::check_support;
use crate::step::{S3Trainer, StepReport};
use crate::supervision::{CollapseWatch, worse_than_untrained};
use mbs_nets::StereoNetwork;
use mbs_nets::checkpoint::TrainedNetworks;
use mbs_nets::host::image_tensor;
use mbs_nets::official::StateDict;

mod logs;
mod report;
mod resume;

use logs::{Interval, open_log, truncate_log, write_line};
pub use logs::{TRAIN_LOG, VAL_LOG, read_log, validation_json};
use report::RunReport;
pub use report::{LOSS_PLOT, TENSORBOARD_DIR, VAL_PLOT, VISUALS_DIR};
use resume::check_resumable;
pub use resume::computing_differences;

/// burn's CPU random generator is one per process: seeding it and drawing
/// a run's fresh weights under this lock keeps a seed's network the same
/// when several runs open at once in one process (as tests do).
pub(crate) static WEIGHT_DRAWING: Mutex<()> = Mutex::new(());

/// File of the run's configuration.
pub const CONFIG_FILE: &str = "config.json";

/// What a run reports while it goes; every method has a default that
/// ignores the event.
pub trait Observer {
    /// After each step, with the throughput of the last logging interval.
    fn on_step(&mut self, _report: &StepReport, _samples_per_second: f64) {}
    /// After each validation (its sheets and curves are drawn by then).
    fn on_validation(&mut self, _steps: usize, _metrics: &ValidationMetrics) {}
    /// When a picture or TensorBoard event could not be written: training
    /// goes on.
    fn on_warning(&mut self, _warning: &TrainError) {}
    /// When training itself looks wrong (supervision has vanished, see
    /// [`crate::supervision::CollapseWatch`]; the message is also in
    /// `train.jsonl` under `warning`), or a training image cannot be used
    /// and is skipped (`train.jsonl` lists it under `skipped` and counts
    /// them under `skipped_images`).
    fn on_alert(&mut self, _message: &str) {}
    /// After each checkpoint.
    fn on_checkpoint(&mut self, _steps: usize, _dir: &Path) {}
}

/// An observer that ignores everything.
pub struct Quiet;

impl Observer for Quiet {}

/// Hands a failed drawing or event write to the observer: pictures must
/// not stop training.
fn warn(observer: &mut dyn Observer, result: Result<(), TrainError>) {
    if let Err(e) = result {
        observer.on_warning(&e);
    }
}

/// Maps of one validation pair for the visual outputs.
#[derive(Debug, Clone)]
pub struct Visual {
    /// `<sample id> <reference>:<target>`.
    pub name: String,
    /// The reference image.
    pub reference: RgbImage,
    /// Ground truth of the pair (`+inf` where unknown).
    pub gt: FloatImage,
    /// The teacher's disparity for the pair.
    pub teacher: FloatImage,
    /// The student's disparity for the widest pair on the same side, divided
    /// by the baseline ratio (so it is comparable with the GT).
    pub student: FloatImage,
    /// Teacher validity mask (0/1, row-major).
    pub teacher_mask: Vec<f32>,
    /// Student validity mask (0/1, row-major).
    pub student_mask: Vec<f32>,
}

/// How a run began.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// From fresh weights.
    Fresh,
    /// From a checkpoint after this many steps.
    Resumed(usize),
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum End {
    /// Every step was taken.
    Finished {
        /// The last validation, if the data has ground truth.
        metrics: Option<Box<ValidationMetrics>>,
    },
    /// Stopped on request after this many steps (a checkpoint was saved).
    Stopped(usize),
}

/// The weights a new run starts from (`train --init`): the teacher of a
/// run or checkpoint folder, or a weights file (an official `.pth` or
/// `.safetensors` state dict, or an `mbs-tool export`).
pub fn initial_weights(path: &Path) -> Result<StateDict, TrainError> {
    if path.is_dir() {
        let teacher = TrainedNetworks::open(path)?.teacher(&Device::flex())?;
        Ok(teacher.state_dict().0)
    } else {
        Ok(StateDict::read(path)?)
    }
}

/// What every process of a distributed run must hold alike: the settings
/// and the manifest's digest.
pub fn run_identity(config: &RunConfig, manifest: &Path) -> Result<serde_json::Value, TrainError> {
    let digest =
        mbs_dataset::checksum::sha256_file(manifest).map_err(|e| TrainError::data(manifest, e))?;
    Ok(serde_json::json!({"settings": config.to_json()?, "manifest_sha256": digest}))
}

/// A training run in an output folder.
pub struct TrainingRun {
    out: PathBuf,
    config: RunConfig,
    samples: Arc<TrainingSamples>,
    validation: ValidationSet,
    trainer: S3Trainer<StereoNetwork>,
    /// The first device holds the weights; all share each step's batch.
    devices: Vec<Device>,
    /// The processes the run is spread over (`None`: this one alone).
    processes: Option<Rc<dyn Collective>>,
    report: RunReport,
}

impl TrainingRun {
    /// Opens the run in `out` on the training data of `manifest`, on the CPU
    /// (see [`TrainingRun::open_on`]).
    pub fn open(
        manifest: &Path,
        out: &Path,
        config: RunConfig,
    ) -> Result<(Self, Start), TrainError> {
        Self::open_on(manifest, out, config, vec![Device::flex()], None, None)
    }

    /// Opens the run in `out` on the training data of `manifest`, training on
    /// `devices` (data parallel when there are several, see
    /// [`S3Trainer::step_parallel`]; the weights live on the first, and a
    /// checkpoint resumes on any number of devices): resumes from the newest checkpoint there, or starts fresh,
    /// from the weights of `init` when given (see [`initial_weights`]; a
    /// resumed run ignores it). Resuming with a configuration that changes
    /// what is computed is refused.
    ///
    /// With `processes`, the run is one rank of a data-parallel run over
    /// several processes (an MPI job, see [`S3Trainer::step_distributed`]),
    /// each on one device: the ranks first [`agree`] on the settings, the
    /// manifest and the checkpoint they found (before any file is
    /// written), then rank 0 alone writes the run's files and validates.
    pub fn open_on(
        manifest: &Path,
        out: &Path,
        config: RunConfig,
        devices: Vec<Device>,
        init: Option<&Path>,
        processes: Option<Rc<dyn Collective>>,
    ) -> Result<(Self, Start), TrainError> {
        config.validate()?;
        let Some(device) = devices.first().cloned() else {
            return Err(TrainError::Config("no device to train on".into()));
        };
        if let Some(processes) = processes.as_ref().filter(|_| devices.len() > 1) {
            return Err(TrainError::Distributed(format!(
                "each of the {} processes trains on one device, not {}: give one device per \
                 process",
                processes.size(),
                devices.len()
            )));
        }
        // What shares each batch: the processes, or this one's devices.
        let (sharers, what) = match &processes {
            Some(processes) => (processes.size(), "processes"),
            None => (devices.len(), "devices"),
        };
        if config.data.batch_size < sharers {
            return Err(TrainError::Config(format!(
                "data.batch_size {} is smaller than the {sharers} {what} that share it",
                config.data.batch_size
            )));
        }
        let named = devices.iter().map(|device| (format!("{device:?}"), device));
        check_support(config.trainer.precision, named)?;
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
        let train_device = device.clone().autodiff();
        let latest = Checkpoint::latest(out)?;
        if let Some(processes) = &processes {
            let mut identity = run_identity(&config, manifest)?;
            identity["checkpoint"] = latest.as_ref().map(|c| c.state.steps).into();
            identity["init"] = init.map(|p| p.display().to_string()).into();
            agree(processes.as_ref(), &identity)?;
        }
        let writer = processes.as_ref().is_none_or(|p| p.rank() == 0);
        // Fresh weights are drawn on the CPU and moved, so a seed gives the
        // same network on every device. Only they need the seed; a
        // checkpoint has its own.
        let init_device = Device::flex().autodiff();
        let drawing = WEIGHT_DRAWING
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if latest.is_none() {
            init_device.seed(config.seed);
        }
        let fresh = config.network.init(&init_device)?;
        // Forking while `fresh` still shares the (lazy) parameters makes
        // burn initialise them where they are and copy them over.
        let mut student = fresh.clone().fork(&train_device);
        drop(fresh);
        drop(drawing);
        if let (None, Some(init)) = (&latest, init) {
            student = student.with_state_dict(&initial_weights(init)?, init)?;
        }
        let mut trainer = S3Trainer::new(student, &config.trainer)?;
        let start = match latest {
            Some(checkpoint) => {
                check_resumable(&checkpoint, &config)?;
                let steps = checkpoint.state.steps;
                let networks = checkpoint.networks()?;
                trainer.restore(
                    networks.student(&train_device)?,
                    networks.teacher(&device)?,
                    checkpoint.optimizer()?,
                    steps,
                    checkpoint.state.loss_scale,
                );
                if writer {
                    truncate_log(&out.join(TRAIN_LOG), steps)?;
                    truncate_log(&out.join(VAL_LOG), steps)?;
                }
                Start::Resumed(steps)
            }
            None => {
                for log in [TRAIN_LOG, VAL_LOG].into_iter().filter(|_| writer) {
                    let path = out.join(log);
                    if path.exists() {
                        fs::remove_file(&path).map_err(|e| TrainError::data(&path, e))?;
                    }
                }
                Start::Fresh
            }
        };
        if let Some(processes) = &processes {
            let steps = trainer.steps_taken();
            check_same_weights(
                processes.as_ref(),
                &[trainer.student(), trainer.teacher()],
                steps,
            )?;
        }
        if writer {
            let config_json = serde_json::to_vec_pretty(&config.to_json()?)
                .map_err(|e| TrainError::Config(e.to_string()))?;
            write_bytes_atomic(&out.join(CONFIG_FILE), &config_json)?;
        }
        let resumed_after = match &start {
            Start::Resumed(steps) => Some(*steps),
            Start::Fresh => None,
        };
        let report = RunReport::new(out, config.network.max_disparity as f32, resumed_after);
        Ok((
            Self {
                report,
                out: out.to_path_buf(),
                config,
                samples: Arc::new(samples),
                validation,
                trainer,
                devices,
                processes,
            },
            start,
        ))
    }

    /// Whether this process writes the run's files and validates: the only
    /// process, or rank 0 of several.
    pub fn is_writer(&self) -> bool {
        self.processes.as_ref().is_none_or(|p| p.rank() == 0)
    }

    /// The run's configuration.
    pub fn config(&self) -> &RunConfig {
        &self.config
    }

    /// Steps taken so far.
    pub fn steps_taken(&self) -> usize {
        self.trainer.steps_taken()
    }

    /// The held-out pairs validation scores (empty without ground truth).
    pub fn validation(&self) -> &ValidationSet {
        &self.validation
    }

    /// The teacher (the network used for inference).
    pub fn teacher(&self) -> &StereoNetwork {
        self.trainer.teacher()
    }

    /// Trains up to the configured number of steps, or until `stop` is set
    /// (then a checkpoint is saved and [`End::Stopped`] returned). An error
    /// that ends the run (an unreadable image, a full disk) first saves a
    /// checkpoint of the steps taken since the last one, when it can.
    pub fn run(
        &mut self,
        observer: &mut dyn Observer,
        stop: &AtomicBool,
    ) -> Result<End, TrainError> {
        let result = self.take_steps(observer, stop);
        if result.is_err() && self.is_writer() {
            let saved = Checkpoint::latest(&self.out)
                .ok()
                .flatten()
                .map(|c| c.state.steps);
            if saved != Some(self.trainer.steps_taken()) && self.trainer.steps_taken() > 0 {
                let saving = self.checkpoint(observer);
                warn(observer, saving);
            }
        }
        result
    }

    fn take_steps(
        &mut self,
        observer: &mut dyn Observer,
        stop: &AtomicBool,
    ) -> Result<End, TrainError> {
        let total = self.config.steps();
        let first = self.trainer.steps_taken();
        let data = self.config.data.clone();
        // Each process of several loads only its share of each batch.
        let items = match &self.processes {
            Some(processes) => share(data.batch_size, processes.size(), processes.rank()),
            None => 0..data.batch_size,
        };
        let mut loader = BatchLoader::start(
            Arc::clone(&self.samples),
            (data.batch_size, items),
            (data.crop_height, data.crop_width),
            self.config.seed,
            (first, total),
            data.loading_threads(),
        );
        let mut log = open_log(&self.out.join(TRAIN_LOG))?;
        let mut interval = Interval::new();
        let mut skipped = std::collections::BTreeSet::new();
        let mut newly_skipped = Vec::new();
        let images = self.samples.samples.len() * self.samples.rig.num_views;
        let skip_limit = (images / 100).max(10);
        let mut watch = CollapseWatch::default();
        let mut alert = None;
        let mut metrics = None;
        let writer = self.is_writer();
        if first == 0 && writer {
            metrics = self.validate(observer)?;
        }
        // The untrained network's score, from this session or the log.
        let untrained_out3 = read_log(&self.out.join(VAL_LOG))
            .ok()
            .and_then(|lines| lines.into_iter().find(|l| l["step"] == 0))
            .and_then(|line| line["ALL"]["out3"].as_f64());
        loop {
            let asked = Instant::now();
            let Some(batch) = loader.next_batch() else {
                break;
            };
            interval.add_data_wait(asked.elapsed());
            let batch = batch?;
            for (path, error) in &batch.skipped {
                if skipped.insert(path.clone()) {
                    observer.on_alert(&format!("skipping an unusable image: {error}"));
                    newly_skipped.push(error.clone());
                }
            }
            if skipped.len() > skip_limit {
                return Err(TrainError::Input(format!(
                    "{} training images could not be used, more than the {skip_limit} a run \
                     skips (1 % of its images, at least 10); check the data with \
                     `mbs-tool validate --deep`",
                    skipped.len()
                )));
            }
            // Several devices take their shares from the host, not through
            // the first one.
            let home = match self.devices.len() {
                1 => self.devices[0].clone(),
                _ => Device::flex(),
            };
            let batch = StepBatch::from_host(batch, &home, &self.config.augment, self.config.seed);
            let report = match &self.processes {
                Some(processes) => {
                    self.trainer
                        .step_distributed(batch, data.batch_size, processes.as_ref())?
                }
                None => self.trainer.step_parallel(batch, &self.devices)?,
            };
            let taken = report.step + 1;
            interval.add(&report);
            observer.on_step(&report, interval.samples_per_second(data.batch_size));
            if let Some(message) = watch.observe(report.step, &report.supervision) {
                observer.on_alert(&message);
                alert = Some(message);
            }
            // Validation first, so that its warning goes into this step's log line.
            let validating = taken % self.config.val_every == 0 || taken == total;
            if let (Some(processes), true) = (&self.processes, validating) {
                let networks = [self.trainer.student(), self.trainer.teacher()];
                check_same_weights(processes.as_ref(), &networks, taken)?;
            }
            if validating && writer {
                metrics = self.validate(observer)?;
                let out3 = metrics.as_ref().and_then(|m| m.all().out(3.0));
                if let (Some(untrained), Some(out3)) = (untrained_out3, out3)
                    && let Some(message) = worse_than_untrained(taken, untrained, out3)
                {
                    observer.on_alert(&message);
                    alert = Some(message);
                }
            }
            if (taken % self.config.log_every == 0 || taken == total) && writer {
                let mut line = interval.json(taken, data.batch_size);
                if let Some(message) = alert.take() {
                    line["warning"] = message.into();
                }
                if !skipped.is_empty() {
                    line["skipped_images"] = skipped.len().into();
                }
                if !newly_skipped.is_empty() {
                    line["skipped"] = std::mem::take(&mut newly_skipped).into();
                }
                write_line(&mut log, &self.out.join(TRAIN_LOG), &line)?;
                let logged = self.report.log_line("train", &line);
                warn(observer, logged);
                interval = Interval::new();
            }
            let mut stopping = stop.load(Ordering::Relaxed);
            if let Some(processes) = &self.processes {
                // Every rank stops at the same step when any was asked to.
                stopping = processes
                    .gather(&[u8::from(stopping)])
                    .iter()
                    .any(|b| b[0] == 1);
            }
            let checkpointing =
                taken % self.config.checkpoint_every == 0 || taken == total || stopping;
            if checkpointing && writer {
                self.checkpoint(observer)?;
            }
            if stopping && taken < total {
                return Ok(End::Stopped(taken));
            }
        }
        if writer {
            warn(observer, self.report.curves());
        }
        Ok(End::Finished {
            metrics: metrics.map(Box::new),
        })
    }

    fn checkpoint(&self, observer: &mut dyn Observer) -> Result<(), TrainError> {
        let steps = self.trainer.steps_taken();
        let dir = checkpoint::save(
            &self.out,
            &self.trainer,
            &self.config,
            self.config.keep_checkpoints,
        )?;
        observer.on_checkpoint(steps, &dir);
        Ok(())
    }

    /// Scores the teacher, logs to `val.jsonl` and draws the visuals;
    /// `None` when there is nothing to score.
    fn validate(
        &mut self,
        observer: &mut dyn Observer,
    ) -> Result<Option<ValidationMetrics>, TrainError> {
        if self.validation.is_empty() {
            return Ok(None);
        }
        let steps = self.trainer.steps_taken();
        let metrics = self
            .validation
            .evaluate(self.trainer.teacher(), &self.devices[0])?;
        let path = self.out.join(VAL_LOG);
        let mut log = open_log(&path)?;
        let line = validation_json(steps, &metrics);
        write_line(&mut log, &path, &line)?;
        warn(observer, self.report.log_line("val", &line));
        let visuals = self
            .validation
            .pairs
            .iter()
            .take(self.config.visual_samples)
            .map(|pair| self.visual(pair))
            .collect::<Result<Vec<_>, _>>()?;
        warn(observer, self.report.visuals(steps, &visuals));
        warn(observer, self.report.curves());
        observer.on_validation(steps, &metrics);
        Ok(Some(metrics))
    }

    /// The maps of one validation pair: the teacher on the pair, the
    /// student on the widest pair of the same side.
    fn visual(&self, pair: &ValidationPair) -> Result<Visual, TrainError> {
        let loaded = pair.load()?;
        let (wide_path, ratio) = &pair.wide_target;
        let wide = mbs_core::formats::rgb::read_rgb(wide_path)?;
        let (width, height) = loaded.reference.dimensions();
        let tensor = |image: &RgbImage| image_tensor(image, &self.devices[0]);
        let reference = tensor(&loaded.reference);
        let wide_target = tensor(&wide);
        let diagnosis = self.trainer.diagnose(StepBatch {
            reference: reference.clone(),
            student_target: wide_target.clone(),
            teacher_target: tensor(&loaded.target),
            augmented_reference: reference,
            augmented_target: wide_target,
            student_sides: vec![pair.side()],
            teacher_sides: vec![pair.side()],
            ratios: vec![*ratio],
        })?;
        let map = |values: Vec<f32>| {
            FloatImage::from_raw(width, height, values)
                .ok_or_else(|| TrainError::Shape("a map of the wrong size".into()))
        };
        let student = diagnosis
            .student_disparity
            .iter()
            .map(|d| d / *ratio as f32)
            .collect();
        let ones = || vec![1.0; (width * height) as usize];
        Ok(Visual {
            name: pair.name.clone(),
            teacher: map(diagnosis.teacher_disparity)?,
            student: map(student)?,
            teacher_mask: diagnosis.teacher_mask.unwrap_or_else(ones),
            student_mask: diagnosis.student_mask.unwrap_or_else(ones),
            reference: loaded.reference,
            gt: loaded.gt,
        })
    }
}
