//! The step loop of a run, a fixed sequence of named phases per step: the
//! next batch (with the images it had to skip), the step on the run's
//! placement, then the periodic actions: watch the supervision, validate,
//! log, honour a stop request, checkpoint.

use std::collections::BTreeSet;
use std::fs::File;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use mbs_batch::HostBatch;

use super::logs::{Interval, open_log, validation_protocol, write_line};
use super::{End, Observer, TRAIN_LOG, TrainingRun, VAL_LOG, read_log, warn};
use crate::checkpoint;
use crate::data::validation::ValidationMetrics;
use crate::data::{BatchLoader, StepBatch};
use crate::drift::DriftWatch;
use crate::error::TrainError;
use crate::step::StepReport;
use crate::supervision::{CollapseWatch, worse_than_untrained};

/// What the step loop carries from one step to the next.
struct StepLoop {
    /// The open `train.jsonl`.
    log: File,
    /// Means of the steps since the last log line.
    interval: Interval,
    /// Every training image skipped so far, and those not yet logged.
    skipped: BTreeSet<PathBuf>,
    newly_skipped: Vec<String>,
    /// Skipped images beyond which the run stops.
    skip_limit: usize,
    watch: CollapseWatch,
    /// A warning for the next log line.
    alert: Option<String>,
    /// The newest validation.
    metrics: Option<ValidationMetrics>,
    /// The untrained network's held-out Out-3, from this session or the log.
    untrained_out3: Option<f64>,
    /// The validations' watch, with the best so far.
    drift: DriftWatch,
}

impl TrainingRun {
    /// Trains from the steps taken to the run's last, or to a stop request.
    pub(super) fn take_steps(
        &mut self,
        observer: &mut dyn Observer,
        stop: &AtomicBool,
    ) -> Result<End, TrainError> {
        let total = self.config.steps();
        let mut loader = self.start_loader();
        let mut state = self.open_step_loop(observer)?;
        loop {
            let asked = Instant::now();
            let Some(batch) = loader.next_batch() else {
                break;
            };
            state.interval.add_data_wait(asked.elapsed());
            let batch = batch?;
            state.note_skipped(&batch, observer)?;
            let report = self.step_on(batch)?;
            let taken = report.step + 1;
            state.observe(&report, self.config.data.batch_size, observer);
            self.validate_if_due(&mut state, taken, observer)?;
            self.log_if_due(&mut state, taken, observer)?;
            let stopping = self.stop_requested(stop);
            let due = taken % self.config.checkpoint_every == 0 || taken == total;
            if (due || stopping) && self.is_writer() {
                self.checkpoint(observer)?;
            }
            if stopping && taken < total {
                return Ok(End::Stopped(taken));
            }
        }
        if self.is_writer() {
            warn(observer, self.report.curves());
        }
        Ok(End::Finished {
            metrics: state.metrics.map(Box::new),
        })
    }

    /// Loads the batches of the steps left ahead of their use: this
    /// process's share of each, when several share them.
    fn start_loader(&self) -> BatchLoader {
        let data = &self.config.data;
        let items = self.strategy.items_loaded(data.batch_size);
        BatchLoader::start(
            Arc::clone(&self.samples),
            (data.batch_size, items),
            (data.crop_height, data.crop_width),
            self.config.seed,
            (self.trainer.steps_taken(), self.config.steps()),
            data.loading_threads(),
        )
    }

    /// The loop's state; a run that starts from step 0 validates first.
    fn open_step_loop(&mut self, observer: &mut dyn Observer) -> Result<StepLoop, TrainError> {
        let images = self.samples.samples.len() * self.samples.rig.num_views;
        let metrics = match self.trainer.steps_taken() == 0 && self.is_writer() {
            true => self.validate(observer)?,
            false => None,
        };
        // Only the validations under this run's protocol compare with the
        // next (a line without one is from before the setting: `pixels`).
        let protocol = self.validation.rules.protocol.name();
        let validations: Vec<_> = read_log(&self.out.join(VAL_LOG))
            .unwrap_or_default()
            .into_iter()
            .filter(|line| validation_protocol(line) == protocol)
            .collect();
        let untrained_out3 = validations
            .iter()
            .find(|l| l["step"] == 0)
            .and_then(|line| line["ALL"]["out3"].as_f64());
        let drift = DriftWatch::resumed(self.config.steps(), &validations);
        // A best checkpoint past the one resumed from belongs to steps
        // that are taken again (and its validation is no longer logged).
        if self.is_writer()
            && checkpoint::best_steps(&self.out).is_some_and(|s| s > self.trainer.steps_taken())
        {
            checkpoint::discard_best(&self.out)?;
        }
        Ok(StepLoop {
            log: open_log(&self.out.join(TRAIN_LOG))?,
            interval: Interval::new(),
            skipped: BTreeSet::new(),
            newly_skipped: Vec::new(),
            skip_limit: (images / 100).max(10),
            watch: CollapseWatch::default(),
            alert: None,
            metrics,
            untrained_out3,
            drift,
        })
    }

    /// One step on `batch` (this process's items) as the run's strategy
    /// takes it, built where the strategy says.
    fn step_on(&mut self, batch: HostBatch) -> Result<StepReport, TrainError> {
        let home = self.strategy.batch_device();
        let batch = StepBatch::from_host(batch, &home, &self.config.augment, self.config.seed);
        let batch_size = self.config.data.batch_size;
        self.strategy.step(&mut self.trainer, batch, batch_size)
    }

    /// Validates at the run's interval and at its end (first, so that a
    /// warning it raises goes into this step's log line).
    fn validate_if_due(
        &mut self,
        state: &mut StepLoop,
        taken: usize,
        observer: &mut dyn Observer,
    ) -> Result<(), TrainError> {
        if !taken.is_multiple_of(self.config.val_every) && taken != self.config.steps() {
            return Ok(());
        }
        let networks = [self.trainer.student(), self.trainer.teacher()];
        self.strategy.check_same_weights(networks, taken)?;
        if !self.is_writer() {
            return Ok(());
        }
        state.metrics = self.validate(observer)?;
        let out3 = state.metrics.as_ref().and_then(|m| m.all()?.out(3.0));
        let Some(out3) = out3 else {
            return Ok(());
        };
        let mut warnings = Vec::new();
        if let Some(untrained) = state.untrained_out3 {
            warnings.extend(worse_than_untrained(taken, untrained, out3));
        }
        let range = state.metrics.as_ref().and_then(|m| m.range);
        let verdict = state.drift.observe(taken, out3, range);
        if verdict.best {
            checkpoint::save_best(&self.out, &self.trainer, &self.config)?;
        }
        for message in warnings.into_iter().chain(verdict.warnings) {
            observer.on_alert(&message);
            state.alert(message);
        }
        Ok(())
    }

    /// Writes the interval's line to `train.jsonl` (and TensorBoard) at the
    /// run's interval and at its end.
    fn log_if_due(
        &mut self,
        state: &mut StepLoop,
        taken: usize,
        observer: &mut dyn Observer,
    ) -> Result<(), TrainError> {
        let due = taken.is_multiple_of(self.config.log_every) || taken == self.config.steps();
        if !due || !self.is_writer() {
            return Ok(());
        }
        let mut line = state.interval.json(taken, self.config.data.batch_size);
        if let Some(message) = state.alert.take() {
            line["warning"] = message.into();
        }
        if !state.skipped.is_empty() {
            line["skipped_images"] = state.skipped.len().into();
        }
        if !state.newly_skipped.is_empty() {
            line["skipped"] = std::mem::take(&mut state.newly_skipped).into();
        }
        write_line(&mut state.log, &self.out.join(TRAIN_LOG), &line)?;
        warn(observer, self.report.log_line("train", &line));
        state.interval = Interval::new();
        Ok(())
    }

    /// Whether this step is the last before a stop: asked of this process,
    /// or of any of several (so that all stop at the same step).
    fn stop_requested(&self, stop: &AtomicBool) -> bool {
        self.strategy.stop_voted(stop.load(Ordering::Relaxed))
    }
}

impl StepLoop {
    /// Reports the images `batch` could not use, once each, and stops the
    /// run when too many could not be used.
    fn note_skipped(
        &mut self,
        batch: &HostBatch,
        observer: &mut dyn Observer,
    ) -> Result<(), TrainError> {
        for (path, error) in &batch.skipped {
            if self.skipped.insert(path.clone()) {
                observer.on_alert(&format!("skipping an unusable image: {error}"));
                self.newly_skipped.push(error.clone());
            }
        }
        if self.skipped.len() > self.skip_limit {
            return Err(TrainError::Input(format!(
                "{} training images could not be used, more than the {} a run skips (1 % of \
                 its images, at least 10); check the data with `mbs-tool validate --deep`",
                self.skipped.len(),
                self.skip_limit
            )));
        }
        Ok(())
    }

    /// Counts the step into the interval, reports it and watches its
    /// supervision for a collapse.
    fn observe(&mut self, report: &StepReport, batch_size: usize, observer: &mut dyn Observer) {
        self.interval.add(report);
        observer.on_step(report, self.interval.samples_per_second(batch_size));
        if let Some(message) = self.watch.observe(report.step, &report.supervision) {
            observer.on_alert(&message);
            self.alert(message);
        }
    }

    /// Adds `message` to the warning of the next log line.
    fn alert(&mut self, message: String) {
        self.alert = Some(match self.alert.take() {
            Some(earlier) => format!("{earlier}; {message}"),
            None => message,
        });
    }
}
