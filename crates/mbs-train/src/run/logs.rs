//! The run's JSONL logs: loss terms per interval (`train.jsonl`) and
//! validation metrics (`val.jsonl`), appended line by line and cut back to
//! a checkpoint's step on resumption.

use std::fs;
use std::io::Write;
use std::path::Path;
use std::time::{Duration, Instant};

use mbs_core::atomic::write_bytes_atomic;
use mbs_eval::{Metrics, Region};
use serde_json::{Value, json};

use crate::data::validation::ValidationMetrics;
use crate::error::TrainError;
use crate::losses::Term;
use crate::step::StepReport;

/// File of the loss log.
pub const TRAIN_LOG: &str = "train.jsonl";
/// File of the validation log.
pub const VAL_LOG: &str = "val.jsonl";

/// Keeps the lines of a JSONL log whose `step` is at most `steps` (and
/// drops a torn last line), rewriting the file atomically.
pub(crate) fn truncate_log(path: &Path, steps: usize) -> Result<(), TrainError> {
    let Some(text) = mbs_core::regular::read_text_if_present(path)? else {
        return Ok(());
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

/// The lines of a JSONL log (a missing file has none; torn lines are
/// skipped).
pub fn read_log(path: &Path) -> Result<Vec<Value>, TrainError> {
    Ok(mbs_core::regular::read_text_if_present(path)?
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect())
}

pub(crate) fn open_log(path: &Path) -> Result<fs::File, TrainError> {
    if let Some(parent) = path.parent() {
        fs::create_dir_all(parent).map_err(|e| TrainError::data(parent, e))?;
    }
    Ok(mbs_core::regular::open_append(path)?)
}

pub(crate) fn write_line(
    file: &mut fs::File,
    path: &Path,
    value: &Value,
) -> Result<(), TrainError> {
    writeln!(file, "{value}").map_err(|e| TrainError::data(path, e))
}

/// Means of the step reports of one logging interval.
pub(crate) struct Interval {
    start: Instant,
    steps: usize,
    loss: f64,
    /// The sums of the terms, per term.
    terms: [f64; Term::COUNT],
    student_mask: f64,
    teacher_mask: f64,
    outside: f64,
    disparity_mean: f64,
    disparity_min: f32,
    disparity_max: f32,
    data_wait: Duration,
    last: Option<StepReport>,
}

impl Interval {
    pub(crate) fn new() -> Self {
        Self {
            start: Instant::now(),
            steps: 0,
            loss: 0.0,
            terms: [0.0; Term::COUNT],
            student_mask: 0.0,
            teacher_mask: 0.0,
            outside: 0.0,
            disparity_mean: 0.0,
            disparity_min: f32::INFINITY,
            disparity_max: f32::NEG_INFINITY,
            data_wait: Duration::ZERO,
            last: None,
        }
    }

    /// Adds the time a step waited for its batch from the loader.
    pub(crate) fn add_data_wait(&mut self, waited: Duration) {
        self.data_wait += waited;
    }

    pub(crate) fn add(&mut self, report: &StepReport) {
        self.steps += 1;
        self.loss += f64::from(report.loss);
        for (term, value) in report.terms.iter() {
            self.terms[term.index()] += f64::from(value.copied().unwrap_or(0.0));
        }
        let supervision = &report.supervision;
        self.student_mask += f64::from(supervision.student_mask.unwrap_or(0.0));
        self.teacher_mask += f64::from(supervision.teacher_mask.unwrap_or(0.0));
        self.outside += f64::from(supervision.outside);
        self.disparity_mean += f64::from(supervision.disparity_mean);
        self.disparity_min = self.disparity_min.min(supervision.disparity_min);
        self.disparity_max = self.disparity_max.max(supervision.disparity_max);
        self.last = Some(*report);
    }

    pub(crate) fn samples_per_second(&self, batch_size: usize) -> f64 {
        let seconds = self.start.elapsed().as_secs_f64();
        if seconds > 0.0 {
            (self.steps * batch_size) as f64 / seconds
        } else {
            0.0
        }
    }

    pub(crate) fn json(&self, steps: usize, batch_size: usize) -> Value {
        let n = self.steps.max(1) as f64;
        let last = self.last.unwrap_or(StepReport {
            step: steps,
            loss: 0.0,
            terms: Default::default(),
            supervision: Default::default(),
            grad_norm: 0.0,
            loss_scale: None,
            lr: 0.0,
            momentum: 0.0,
        });
        let mean = |on: Option<f32>, sum: f64| on.map(|_| sum / n);
        let mut line = json!({
            "step": steps,
            "loss": self.loss / n,
            "supervision": {
                "student_mask": mean(last.supervision.student_mask, self.student_mask),
                "teacher_mask": mean(last.supervision.teacher_mask, self.teacher_mask),
                "outside": self.outside / n,
                "disparity": {
                    "min": self.disparity_min,
                    "mean": self.disparity_mean / n,
                    "max": self.disparity_max,
                },
            },
            "lr": last.lr,
            "momentum": last.momentum,
            "grad_norm": last.grad_norm,
            "samples_per_s": self.samples_per_second(batch_size),
            "data_wait_ms": 1e3 * self.data_wait.as_secs_f64() / n,
        });
        for term in Term::ALL {
            line[term.name()] = json!(mean(last.terms.value(term), self.terms[term.index()]));
        }
        if let Some(scale) = last.loss_scale {
            line["loss_scale"] = json!(scale);
        }
        line
    }
}

/// The protocol a `val.jsonl` line was scored under; a line without one
/// is from a run older than `data.val_protocol`, scored under `pixels`.
pub fn validation_protocol(line: &Value) -> &str {
    line["protocol"].as_str().unwrap_or("pixels")
}

/// A `val.jsonl` line.
pub fn validation_json(steps: usize, metrics: &ValidationMetrics) -> Value {
    let region = |m: Option<Metrics>| {
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
    let range = metrics.range.map(|r| {
        json!({
            "predicted_p95": r.predicted,
            "truth_p95": r.truth,
        })
    });
    json!({
        "step": steps,
        "protocol": metrics.report.rules().protocol.name(),
        "pairs": metrics.pairs,
        "ALL": region(metrics.region(Region::All)),
        "NOC": region(metrics.region(Region::Noc)),
        "OCC": region(metrics.region(Region::Occ)),
        "range": range,
    })
}
