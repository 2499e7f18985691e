//! What `train` shows while it runs: a progress bar with the loss terms
//! and samples/s, a line per validation, warnings, and a closing summary.
//! (The run itself draws its sheets and curves and writes TensorBoard
//! events: `mbs_train::run`.)

use std::path::{Path, PathBuf};

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use mbs_train::data::validation::ValidationMetrics;
use mbs_train::run::{
    LOSS_PLOT, Observer, TENSORBOARD_DIR, TRAIN_LOG, VAL_LOG, VAL_PLOT, VISUALS_DIR, read_log,
};
use mbs_train::step::StepReport;
use mbs_train::{RunConfig, TrainError};

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

    /// Prints the first and last validation and where the outputs are.
    pub fn summary(&self, last: Option<&ValidationMetrics>) {
        let val = read_log(&self.out.join(VAL_LOG)).unwrap_or_default();
        if let (Some(first), Some(_)) = (val.first(), last) {
            eprintln!("\nteacher on held-out pairs   EPE ALL   Out-3 ALL   Out-3 NOC   Out-3 OCC");
            for line in [first, val.last().unwrap_or(first)] {
                let get = |region: &str, key: &str| {
                    line[region][key]
                        .as_f64()
                        .map_or("-".to_string(), |v| format!("{v:.2}"))
                };
                eprintln!(
                    "step {:<7}                {:>7} {:>9} % {:>9} % {:>9} %",
                    line["step"].as_u64().unwrap_or(0),
                    get("ALL", "epe"),
                    get("ALL", "out3"),
                    get("NOC", "out3"),
                    get("OCC", "out3"),
                );
            }
        }
        eprintln!(
            "\nOutputs in {}: {TRAIN_LOG}, {VAL_LOG}, {LOSS_PLOT}, {VAL_PLOT}, {VISUALS_DIR}/, checkpoints/,\n\
             {TENSORBOARD_DIR}/ (watch with: tensorboard --logdir {})",
            self.out.display(),
            self.out.display()
        );
    }
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
            "step {steps}: validation on {} pairs: EPE {epe} px, Out-3 ALL {} NOC {} OCC {}",
            metrics.pairs,
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
