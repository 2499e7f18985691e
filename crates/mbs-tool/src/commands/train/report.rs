//! What `train` shows while it runs: a progress bar with the loss terms
//! and samples/s, a line per validation, warnings, and a closing summary.
//! (The run itself draws its sheets and curves and writes TensorBoard
//! events: `mbs_train::run`.)

use std::path::{Path, PathBuf};

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use mbs_nets::checkpoint::CHECKPOINTS_DIR;
use mbs_train::checkpoint::BEST_DIR;
use mbs_train::data::validation::ValidationMetrics;
use mbs_train::drift::DRIFT_POINTS;
use mbs_train::run::{
    LOSS_PLOT, Observer, TENSORBOARD_DIR, TRAIN_LOG, VAL_LOG, VAL_PLOT, VISUALS_DIR, read_log,
    validation_protocol,
};
use mbs_train::step::StepReport;
use mbs_train::{RunConfig, TrainError};
use serde_json::Value;

/// The progress bar and lines of one run.
pub struct Report {
    out: PathBuf,
    bar: ProgressBar,
    validation: String,
    /// First warning (a picture that could not be drawn).
    error: Option<String>,
}

impl Report {
    /// A report for a run in `out` that has taken `steps` steps.
    pub fn new(out: &Path, config: &RunConfig, steps: usize) -> anyhow::Result<Self> {
        let bar = ProgressBar::new(config.steps() as u64);
        let style = ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} steps (ETA {eta}) {msg}",
        )
        .context("progress bar template")?;
        bar.set_style(style);
        bar.set_position(steps as u64);
        Ok(Self {
            out: out.to_path_buf(),
            bar,
            validation: String::new(),
            error: None,
        })
    }

    /// Prints a line above the bar (or on stderr when the bar is hidden).
    fn line(&self, text: &str) {
        if self.bar.is_hidden() {
            eprintln!("{text}");
        } else {
            self.bar.println(text);
        }
    }

    /// Ends the bar; an error if a picture could not be drawn.
    pub fn finish(&mut self) -> anyhow::Result<()> {
        self.bar.finish_and_clear();
        match self.error.take() {
            Some(e) => Err(anyhow::anyhow!("drawing the visual outputs: {e}")),
            None => Ok(()),
        }
    }

    /// Prints the first, the best and the last validation, which teacher
    /// to use when the last is worse than the best, and where the outputs
    /// are.
    pub fn summary(&self, last: Option<&ValidationMetrics>) {
        let val = read_log(&self.out.join(VAL_LOG)).unwrap_or_default();
        if let (Some(first), Some(_)) = (val.first(), last) {
            let protocol = val.last().map_or("pixels", validation_protocol);
            eprintln!("\nteacher on held-out pairs ({protocol} protocol)");
            eprintln!("                           EPE ALL   Out-3 ALL   Out-3 NOC   Out-3 OCC");
            let final_line = val.last().unwrap_or(first);
            let best = best_validation(&val);
            let mut lines = vec![("", first)];
            if let Some(best) = best.filter(|b| b["step"] != final_line["step"]) {
                lines.push((" (best)", best));
            }
            lines.push(("", final_line));
            for (label, line) in lines {
                print_validation(label, line);
            }
            self.best_teacher(best, final_line);
        }
        eprintln!(
            "\nOutputs in {}: {TRAIN_LOG}, {VAL_LOG}, {LOSS_PLOT}, {VAL_PLOT}, {VISUALS_DIR}/, checkpoints/,\n\
             {TENSORBOARD_DIR}/ (watch with: tensorboard --logdir {})",
            self.out.display(),
            self.out.display()
        );
    }

    /// Says where the best teacher is, and warns when the final one is
    /// worse by more than [`DRIFT_POINTS`].
    fn best_teacher(&self, best: Option<&Value>, final_line: &Value) {
        let out3 = |line: &Value| line["ALL"]["out3"].as_f64();
        let Some(best) = best else { return };
        let (Some(best_out3), Some(final_out3)) = (out3(best), out3(final_line)) else {
            return;
        };
        let dir = self.out.join(CHECKPOINTS_DIR).join(BEST_DIR);
        let step = best["step"].as_u64().unwrap_or(0);
        if final_out3 > best_out3 + DRIFT_POINTS {
            eprintln!(
                "\nwarning: the final teacher (Out-3 ALL {final_out3:.2} %) is worse than the best, \
                 {best_out3:.2} % at step {step}; use that one: --checkpoint {}",
                dir.display()
            );
        } else {
            eprintln!(
                "\nbest validation: step {step} (Out-3 ALL {best_out3:.2} %), its teacher in {}",
                dir.display()
            );
        }
    }
}

/// The validation after step 0 with the lowest Out-3 ALL (the first of
/// equals), as the run's [`mbs_train::drift::DriftWatch`] picks it.
fn best_validation(val: &[Value]) -> Option<&Value> {
    val.iter()
        .filter(|line| line["step"] != 0)
        .filter(|line| line["ALL"]["out3"].is_f64())
        .fold(None, |best: Option<&Value>, line| match best {
            Some(b) if b["ALL"]["out3"].as_f64() <= line["ALL"]["out3"].as_f64() => Some(b),
            _ => Some(line),
        })
}

/// One row of the summary's table.
fn print_validation(label: &str, line: &Value) {
    let get = |region: &str, key: &str| {
        line[region][key]
            .as_f64()
            .map_or("-".to_string(), |v| format!("{v:.2}"))
    };
    let step = format!("{}{label}", line["step"].as_u64().unwrap_or(0));
    eprintln!(
        "step {step:<14}         {:>7} {:>9} % {:>9} % {:>9} %",
        get("ALL", "epe"),
        get("ALL", "out3"),
        get("NOC", "out3"),
        get("OCC", "out3"),
    );
}

impl Observer for Report {
    fn on_step(&mut self, report: &StepReport, samples_per_second: f64) {
        self.bar.set_position(report.step as u64 + 1);
        let share = |name: &str, value: Option<f32>| {
            value.map_or(String::new(), |v| format!(" {name} {:.0}%", 100.0 * v))
        };
        let supervision = &report.supervision;
        let terms: Vec<String> = report
            .terms
            .iter()
            .filter_map(|(term, value)| Some(format!("{} {:.3}", term.letter(), value?)))
            .collect();
        self.bar.set_message(format!(
            "loss {:.3} ({}) masks{}{} {:.1} samples/s{}",
            report.loss,
            terms.join(" "),
            share("s", supervision.student_mask),
            share("t", supervision.teacher_mask),
            samples_per_second,
            self.validation,
        ));
    }

    fn on_validation(&mut self, steps: usize, metrics: &ValidationMetrics) {
        let value = mbs_train::run::validation_json(steps, metrics);
        let out3 = |region: &str| {
            value[region]["out3"]
                .as_f64()
                .map_or("-".into(), |v| format!("{v:.2} %"))
        };
        let epe = value["ALL"]["epe"]
            .as_f64()
            .map_or("-".into(), |v| format!("{v:.3}"));
        self.line(&format!(
            "step {steps}: validation on {} pairs ({} protocol): EPE {epe} px, Out-3 ALL {} NOC \
             {} OCC {}",
            metrics.pairs,
            metrics.report.rules().protocol,
            out3("ALL"),
            out3("NOC"),
            out3("OCC")
        ));
        self.validation = format!(" | val Out-3 {}", out3("ALL"));
    }

    fn on_alert(&mut self, message: &str) {
        self.line(&format!("warning: {message}"));
    }

    fn on_warning(&mut self, warning: &TrainError) {
        self.line(&format!("warning: {warning}"));
        self.error.get_or_insert_with(|| warning.to_string());
    }
}
