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
//! <out>/checkpoints/best/   the same, of the best validation so far
//! ```
//!
//! Opening a folder that has a checkpoint resumes from it: logs are cut
//! back to the checkpoint's step and batch `k` is drawn exactly as in an
//! uninterrupted run (see [`crate::data::step_rng`]).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use burn::tensor::Device;
use mbs_core::{FloatImage, RgbImage};

use crate::checkpoint::{self, Checkpoint};
use crate::config::RunConfig;
use crate::data::StepBatch;
use crate::data::validation::{ValidationMetrics, ValidationPair};
use crate::data::{TrainingSamples, ValidationSet};
use crate::error::TrainError;
use crate::step::{S3Trainer, StepReport};
use mbs_nets::StereoNetwork;
use mbs_nets::checkpoint::TrainedNetworks;
use mbs_nets::host::image_tensor;
use mbs_nets::official::StateDict;

mod logs;
pub(crate) mod open;
mod placement;
mod report;
mod resume;
mod steps;

pub use logs::{TRAIN_LOG, VAL_LOG, read_log, validation_json, validation_protocol};
use logs::{open_log, write_line};
pub use placement::{Devices, Ranks, Strategy, place};
use report::RunReport;
pub use report::{LOSS_PLOT, TENSORBOARD_DIR, VAL_PLOT, VISUALS_DIR};
pub use resume::computing_differences;

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

/// A training run in an output folder.
pub struct TrainingRun {
    out: PathBuf,
    config: RunConfig,
    samples: Arc<TrainingSamples>,
    validation: ValidationSet,
    trainer: S3Trainer<StereoNetwork>,
    /// Where it trains: this process's devices (the first holds the
    /// weights) and the processes it is spread over.
    strategy: Box<dyn Strategy<StereoNetwork>>,
    report: RunReport,
    /// The writer's hold on the folder (locked for as long as the run
    /// lives); `None` on the other ranks.
    _folder: Option<mbs_core::out_dir::OutDir>,
}

impl TrainingRun {
    /// The run the launcher opened: in `out`, with `config`, on `data`
    /// (the training samples and the validation pairs), with `trainer`'s
    /// weights, trained as `strategy` places it.
    pub(crate) fn assemble(
        out: &Path,
        config: RunConfig,
        (samples, validation): (TrainingSamples, ValidationSet),
        trainer: S3Trainer<StereoNetwork>,
        strategy: Box<dyn Strategy<StereoNetwork>>,
        start: Start,
    ) -> Self {
        let resumed_after = match start {
            Start::Resumed(steps) => Some(steps),
            Start::Fresh => None,
        };
        let report = RunReport::new(out, config.network.max_disparity as f32, resumed_after);
        Self {
            report,
            out: out.to_path_buf(),
            config,
            samples: Arc::new(samples),
            validation,
            trainer,
            strategy,
            _folder: None,
        }
    }

    /// The run holding `folder`, its output folder, for as long as it
    /// lives (the writer's; `None` on the other ranks).
    pub(crate) fn holding(mut self, folder: Option<mbs_core::out_dir::OutDir>) -> Self {
        self._folder = folder;
        self
    }

    /// Whether this process writes the run's files and validates: the only
    /// process, or rank 0 of several.
    pub fn is_writer(&self) -> bool {
        self.strategy.writes()
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
            .evaluate(self.trainer.teacher(), &self.strategy.devices()[0])?;
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
        let tensor = |image: &RgbImage| image_tensor(image, &self.strategy.devices()[0]);
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
