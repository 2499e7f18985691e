//! A whole training run in an output folder: data loading ahead of the
//! step, S3 steps, loss logs (`train.jsonl`), periodic validation
//! (`val.jsonl`), checkpoints and resumption.
//!
//! ```text
//! <out>/config.json         the run's complete configuration
//! <out>/train.jsonl         loss terms, LR, momentum, samples/s every `log_every` steps
//! <out>/val.jsonl           EPE and Out-x over ALL/NOC/OCC every `val_every` steps
//! <out>/checkpoints/step-N/ student, teacher, optimiser, state.json
//! ```
//!
//! Opening a folder that has a checkpoint resumes from it: logs are cut
//! back to the checkpoint's step and batch `k` is drawn exactly as in an
//! uninterrupted run (see [`crate::data::step_rng`]).

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use burn::tensor::Device;
use mbs_core::atomic::write_bytes_atomic;
use mbs_core::metrics::{Metrics, Region};
use mbs_core::{FloatImage, RgbImage};
use mbs_dataset::Manifest;
use serde_json::{Value, json};

use crate::backbone::CostVolumeNet;
use crate::checkpoint::{self, Checkpoint};
use crate::config::RunConfig;
use crate::data::StepBatch;
use crate::data::validation::{ValidationMetrics, ValidationPair};
use crate::data::{BatchLoader, TrainingSamples, ValidationSet};
use crate::error::TrainError;
use crate::host::image_tensor;
use crate::step::{S3Trainer, StepReport};

/// File of the loss log.
pub const TRAIN_LOG: &str = "train.jsonl";
/// File of the validation log.
pub const VAL_LOG: &str = "val.jsonl";
/// File of the run's configuration.
pub const CONFIG_FILE: &str = "config.json";

/// Keys that may change between a run and its resumption: they do not
/// change what is computed.
const OPERATIONAL_KEYS: [&str; 6] = [
    "log_every",
    "val_every",
    "checkpoint_every",
    "keep_checkpoints",
    "visual_samples",
    "data",
];

/// What a run reports while it goes; every method has a default that
/// ignores the event.
pub trait Observer {
    /// After each step, with the throughput of the last logging interval.
    fn on_step(&mut self, _report: &StepReport, _samples_per_second: f64) {}
    /// After each validation, with the visual samples.
    fn on_validation(&mut self, _steps: usize, _metrics: &ValidationMetrics, _visuals: &[Visual]) {}
    /// After each checkpoint.
    fn on_checkpoint(&mut self, _steps: usize, _dir: &Path) {}
}

/// An observer that ignores everything.
pub struct Quiet;

impl Observer for Quiet {}

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

/// A training run in an output folder.
pub struct TrainingRun {
    out: PathBuf,
    config: RunConfig,
    samples: Arc<TrainingSamples>,
    validation: ValidationSet,
    trainer: S3Trainer<CostVolumeNet>,
    device: Device,
}

impl TrainingRun {
    /// Opens the run in `out` on the training data of `manifest`, on the CPU
    /// (see [`TrainingRun::open_on`]).
    pub fn open(
        manifest: &Path,
        out: &Path,
        config: RunConfig,
    ) -> Result<(Self, Start), TrainError> {
        Self::open_on(manifest, out, config, Device::flex())
    }

    /// Opens the run in `out` on the training data of `manifest`, training on
    /// `device`: resumes from the newest checkpoint there, or starts fresh.
    /// Resuming with a configuration that changes what is computed is refused.
    pub fn open_on(
        manifest: &Path,
        out: &Path,
        config: RunConfig,
        device: Device,
    ) -> Result<(Self, Start), TrainError> {
        config.validate()?;
        let parsed = Manifest::load(manifest)?;
        let crop = (config.data.crop_height, config.data.crop_width);
        let samples = TrainingSamples::from_manifest(manifest, &parsed, crop)?;
        let validation = ValidationSet::from_manifest(
            manifest,
            &parsed,
            &config.data.val_pairs,
            config.data.val_split,
            config.data.val_samples,
        )?;
        let train_device = device.clone().autodiff();
        let latest = Checkpoint::latest(out)?;
        if latest.is_none() {
            // Only fresh weights need the seed; a checkpoint has its own.
            train_device.seed(config.seed);
        }
        let student = config.network.init(&train_device)?;
        let mut trainer = S3Trainer::new(student, &config.trainer)?;
        let start = match latest {
            Some(checkpoint) => {
                check_resumable(&checkpoint, &config)?;
                let steps = checkpoint.state.steps;
                trainer.restore(
                    checkpoint.student(&train_device)?,
                    checkpoint.teacher(&device)?,
                    checkpoint.optimizer()?,
                    steps,
                );
                truncate_log(&out.join(TRAIN_LOG), steps)?;
                truncate_log(&out.join(VAL_LOG), steps)?;
                Start::Resumed(steps)
            }
            None => {
                for log in [TRAIN_LOG, VAL_LOG] {
                    let path = out.join(log);
                    if path.exists() {
                        fs::remove_file(&path).map_err(|e| TrainError::data(&path, e))?;
                    }
                }
                Start::Fresh
            }
        };
        let config_json = serde_json::to_vec_pretty(&config.to_json()?)
            .map_err(|e| TrainError::Config(e.to_string()))?;
        let config_path = out.join(CONFIG_FILE);
        write_bytes_atomic(&config_path, &config_json)?;
        Ok((
            Self {
                out: out.to_path_buf(),
                config,
                samples: Arc::new(samples),
                validation,
                trainer,
                device,
            },
            start,
        ))
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
    pub fn teacher(&self) -> &CostVolumeNet {
        self.trainer.teacher()
    }

    /// Trains up to the configured number of steps, or until `stop` is set
    /// (then a checkpoint is saved and [`End::Stopped`] returned).
    pub fn run(
        &mut self,
        observer: &mut dyn Observer,
        stop: &AtomicBool,
    ) -> Result<End, TrainError> {
        let total = self.config.steps();
        let first = self.trainer.steps_taken();
        let data = &self.config.data;
        let mut loader = BatchLoader::start(
            Arc::clone(&self.samples),
            data.batch_size,
            (data.crop_height, data.crop_width),
            self.config.seed,
            (first, total),
            data.workers,
        );
        let mut log = open_log(&self.out.join(TRAIN_LOG))?;
        let mut interval = Interval::new();
        let mut metrics = None;
        if first == 0 {
            metrics = self.validate(observer)?;
        }
        while let Some(batch) = loader.next_batch() {
            let batch =
                batch?.into_step_batch(&self.device, &self.config.augment, self.config.seed);
            let report = self.trainer.step(batch)?;
            let taken = report.step + 1;
            interval.add(&report);
            observer.on_step(&report, interval.samples_per_second(data.batch_size));
            if taken % self.config.log_every == 0 || taken == total {
                write_line(
                    &mut log,
                    &self.out.join(TRAIN_LOG),
                    &interval.json(taken, data.batch_size),
                )?;
                interval = Interval::new();
            }
            if taken % self.config.val_every == 0 || taken == total {
                metrics = self.validate(observer)?;
            }
            let stopping = stop.load(Ordering::Relaxed);
            if taken % self.config.checkpoint_every == 0 || taken == total || stopping {
                self.checkpoint(observer)?;
            }
            if stopping && taken < total {
                return Ok(End::Stopped(taken));
            }
        }
        Ok(End::Finished {
            metrics: metrics.map(Box::new),
        })
    }

    fn checkpoint(&self, observer: &mut dyn Observer) -> Result<(), TrainError> {
        let steps = self.trainer.steps_taken();
        let dir = checkpoint::save(
            &self.out,
            self.trainer.student(),
            self.trainer.teacher(),
            self.trainer.optimizer(),
            &self.config,
            steps,
            self.config.keep_checkpoints,
        )?;
        observer.on_checkpoint(steps, &dir);
        Ok(())
    }

    /// Scores the teacher, logs to `val.jsonl` and draws the visuals;
    /// `None` when there is nothing to score.
    fn validate(
        &self,
        observer: &mut dyn Observer,
    ) -> Result<Option<ValidationMetrics>, TrainError> {
        if self.validation.is_empty() {
            return Ok(None);
        }
        let steps = self.trainer.steps_taken();
        let metrics = self
            .validation
            .evaluate(self.trainer.teacher(), &self.device)?;
        let path = self.out.join(VAL_LOG);
        let mut log = open_log(&path)?;
        write_line(&mut log, &path, &validation_json(steps, &metrics))?;
        let visuals = self
            .validation
            .pairs
            .iter()
            .take(self.config.visual_samples)
            .map(|pair| self.visual(pair))
            .collect::<Result<Vec<_>, _>>()?;
        observer.on_validation(steps, &metrics, &visuals);
        Ok(Some(metrics))
    }

    /// The maps of one validation pair: the teacher on the pair, the
    /// student on the widest pair of the same side.
    fn visual(&self, pair: &ValidationPair) -> Result<Visual, TrainError> {
        let loaded = pair.load()?;
        let (wide_path, ratio) = &pair.wide_target;
        let wide = mbs_core::formats::rgb::read_rgb(wide_path)?;
        let (width, height) = loaded.reference.dimensions();
        let tensor = |image: &RgbImage| image_tensor(image, &self.device);
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

/// Refuses to resume `checkpoint` under a configuration that computes
/// something else (only the keys in [`OPERATIONAL_KEYS`] may differ, and
/// `data` only in its loading and validation settings).
fn check_resumable(checkpoint: &Checkpoint, config: &RunConfig) -> Result<(), TrainError> {
    let strip = |mut value: Value| {
        if let Value::Object(map) = &mut value {
            for key in OPERATIONAL_KEYS {
                if key == "data" {
                    if let Some(Value::Object(data)) = map.get_mut("data") {
                        for operational in ["workers", "val_pairs", "val_samples", "val_split"] {
                            data.remove(operational);
                        }
                    }
                } else {
                    map.remove(key);
                }
            }
        }
        value
    };
    let saved = strip(checkpoint.state.config.clone());
    let wanted = strip(config.to_json()?);
    if saved != wanted {
        let mut differing = Vec::new();
        diff(&saved, &wanted, "", &mut differing);
        return Err(TrainError::checkpoint(
            &checkpoint.dir,
            format!(
                "was trained with other settings ({}); use a new --out, or --restart to discard it",
                differing.join(", ")
            ),
        ));
    }
    Ok(())
}

/// Dotted paths where `a` and `b` differ.
fn diff(a: &Value, b: &Value, prefix: &str, out: &mut Vec<String>) {
    match (a, b) {
        (Value::Object(a), Value::Object(b)) => {
            for key in a.keys().chain(b.keys().filter(|k| !a.contains_key(*k))) {
                let path = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                match (a.get(key), b.get(key)) {
                    (Some(x), Some(y)) => diff(x, y, &path, out),
                    (Some(x), None) => out.push(format!("{path}: {x} -> missing")),
                    (None, Some(y)) => out.push(format!("{path}: missing -> {y}")),
                    (None, None) => {}
                }
            }
        }
        (a, b) if a != b => out.push(format!("{prefix}: {a} -> {b}")),
        _ => {}
    }
}

/// Keeps the lines of a JSONL log whose `step` is at most `steps` (and
/// drops a torn last line), rewriting the file atomically.
fn truncate_log(path: &Path, steps: usize) -> Result<(), TrainError> {
    let text = match fs::read_to_string(path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(TrainError::data(path, e)),
    };
    let kept: String = text
        .lines()
        .filter(|line| {
            serde_json::from_str::<Value>(line)
                .ok()
                .and_then(|v| v.get("step").and_then(Value::as_u64))
                .is_some_and(|step| step as usize <= steps)
        })
        .map(|line| format!("{line}\n"))
        .collect();
    Ok(write_bytes_atomic(path, kept.as_bytes())?)
}

fn open_log(path: &Path) -> Result<fs::File, TrainError> {
    if let Some(parent) = path.parent() {
        fs::create_dir_all(parent).map_err(|e| TrainError::data(parent, e))?;
    }
    fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .map_err(|e| TrainError::data(path, e))
}

fn write_line(file: &mut fs::File, path: &Path, value: &Value) -> Result<(), TrainError> {
    writeln!(file, "{value}").map_err(|e| TrainError::data(path, e))
}

/// Means of the step reports of one logging interval.
struct Interval {
    start: Instant,
    steps: usize,
    loss: f64,
    geometry: f64,
    photometric: f64,
    smoothness: f64,
    last: Option<StepReport>,
}

impl Interval {
    fn new() -> Self {
        Self {
            start: Instant::now(),
            steps: 0,
            loss: 0.0,
            geometry: 0.0,
            photometric: 0.0,
            smoothness: 0.0,
            last: None,
        }
    }

    fn add(&mut self, report: &StepReport) {
        self.steps += 1;
        self.loss += f64::from(report.loss);
        self.geometry += f64::from(report.terms.geometry.unwrap_or(0.0));
        self.photometric += f64::from(report.terms.photometric.unwrap_or(0.0));
        self.smoothness += f64::from(report.terms.smoothness.unwrap_or(0.0));
        self.last = Some(*report);
    }

    fn samples_per_second(&self, batch_size: usize) -> f64 {
        let seconds = self.start.elapsed().as_secs_f64();
        if seconds > 0.0 {
            (self.steps * batch_size) as f64 / seconds
        } else {
            0.0
        }
    }

    fn json(&self, steps: usize, batch_size: usize) -> Value {
        let n = self.steps.max(1) as f64;
        let last = self.last.unwrap_or(StepReport {
            step: steps,
            loss: 0.0,
            terms: Default::default(),
            grad_norm: 0.0,
            lr: 0.0,
            momentum: 0.0,
        });
        let term = |on: Option<f32>, sum: f64| on.map(|_| sum / n);
        json!({
            "step": steps,
            "loss": self.loss / n,
            "geometry": term(last.terms.geometry, self.geometry),
            "photometric": term(last.terms.photometric, self.photometric),
            "smoothness": term(last.terms.smoothness, self.smoothness),
            "lr": last.lr,
            "momentum": last.momentum,
            "grad_norm": last.grad_norm,
            "samples_per_s": self.samples_per_second(batch_size),
        })
    }
}

/// A `val.jsonl` line.
pub fn validation_json(steps: usize, metrics: &ValidationMetrics) -> Value {
    let region = |m: Option<&Metrics>| {
        m.map(|m| {
            json!({
                "pixels": m.pixels,
                "epe": m.epe,
                "out1": m.out(1.0),
                "out2": m.out(2.0),
                "out3": m.out(3.0),
            })
        })
    };
    json!({
        "step": steps,
        "pairs": metrics.pairs,
        "ALL": region(metrics.region(Region::All)),
        "NOC": region(metrics.region(Region::Noc)),
        "OCC": region(metrics.region(Region::Occ)),
    })
}
