//! What `train` shows and draws while it runs: a progress bar with the loss
//! terms and samples/s, a line per validation, contact sheets of the
//! validation pairs, and the loss and validation curves as PNGs.

use std::path::{Path, PathBuf};

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use mbs_core::formats::rgb::write_rgb_png;
use mbs_train::RunConfig;
use mbs_train::data::validation::ValidationMetrics;
use mbs_train::run::{Observer, TRAIN_LOG, VAL_LOG, Visual};
use mbs_train::step::StepReport;
use serde_json::Value;

use crate::cli::report_error::describe;
use mbs_viz::{LineChart, Series, colorize_disparity, side_by_side, weight_map_image};

/// The curves of a run.
pub const LOSS_PLOT: &str = "loss.png";
/// The validation curves of a run.
pub const VAL_PLOT: &str = "val.png";
/// Folder of the contact sheets.
pub const VISUALS_DIR: &str = "visuals";

/// The progress bar and drawings of one run.
pub struct Report {
    out: PathBuf,
    bar: ProgressBar,
    max_disparity: f32,
    validation: String,
    /// First error met while drawing (drawings must not stop training).
    error: Option<anyhow::Error>,
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
            max_disparity: config.network.max_disparity as f32,
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

    /// Draws the contact sheet of each visual into `visuals/step-N/`.
    fn draw_visuals(&self, steps: usize, visuals: &[Visual]) -> anyhow::Result<()> {
        let dir = self.out.join(VISUALS_DIR).join(format!("step-{steps:07}"));
        for (i, visual) in visuals.iter().enumerate() {
            let colour = |map: &mbs_core::FloatImage| colorize_disparity(map, self.max_disparity);
            let weights = weight_map_image(
                &visual.reference,
                &visual.teacher_mask,
                &visual.student_mask,
            )?;
            let (teacher, student, gt) = (
                colour(&visual.teacher),
                colour(&visual.student),
                colour(&visual.gt),
            );
            let sheet = side_by_side(&[&visual.reference, &teacher, &student, &gt, &weights])?;
            let name: String = visual
                .name
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
                .collect();
            write_rgb_png(&dir.join(format!("{i:02}_{name}.png")), &sheet)?;
        }
        Ok(())
    }

    /// Redraws `loss.png` and `val.png` from the logs.
    fn draw_curves(&self) -> anyhow::Result<()> {
        let train = read_log(&self.out.join(TRAIN_LOG))?;
        let losses: Vec<Series> = ["loss", "geometry", "photometric", "smoothness"]
            .iter()
            .map(|key| series(&train, key, &[key]))
            .filter(|s| !s.points.is_empty())
            .collect();
        if !losses.is_empty() {
            LineChart {
                title: "S3 loss terms (unweighted)".into(),
                x_label: "training step".into(),
                y_label: "loss (log scale)".into(),
                log_y: true,
                series: losses,
            }
            .write_png(&self.out.join(LOSS_PLOT))?;
        }
        let val = read_log(&self.out.join(VAL_LOG))?;
        let out3: Vec<Series> = ["ALL", "NOC", "OCC"]
            .iter()
            .map(|region| series(&val, &format!("Out-3 {region}"), &[region, "out3"]))
            .filter(|s| !s.points.is_empty())
            .collect();
        if !out3.is_empty() {
            LineChart {
                title: "Validation: teacher Out-3 on held-out pairs".into(),
                x_label: "training step".into(),
                y_label: "Out-3 (% of pixels)".into(),
                log_y: false,
                series: out3,
            }
            .write_png(&self.out.join(VAL_PLOT))?;
        }
        Ok(())
    }

    fn keep_error(&mut self, result: anyhow::Result<()>) {
        if let Err(e) = result {
            self.line(&format!("warning: {}", describe(&e)));
            self.error.get_or_insert(e);
        }
    }

    /// Ends the bar and draws the final curves.
    pub fn finish(&mut self) -> anyhow::Result<()> {
        self.bar.finish_and_clear();
        let curves = self.draw_curves();
        self.keep_error(curves);
        match self.error.take() {
            Some(e) => Err(e.context("drawing the visual outputs")),
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
            "\nOutputs in {}: {TRAIN_LOG}, {VAL_LOG}, {LOSS_PLOT}, {VAL_PLOT}, {VISUALS_DIR}/, checkpoints/",
            self.out.display()
        );
    }
}

impl Observer for Report {
    fn on_step(&mut self, report: &StepReport, samples_per_second: f64) {
        let term = |name: &str, value: Option<f32>| {
            value.map_or(String::new(), |v| format!(" {name} {v:.3}"))
        };
        self.bar.set_position(report.step as u64 + 1);
        self.bar.set_message(format!(
            "loss {:.3} ({}{}{} ) {:.1} samples/s{}",
            report.loss,
            term("g", report.terms.geometry).trim_start(),
            term("p", report.terms.photometric),
            term("s", report.terms.smoothness),
            samples_per_second,
            self.validation,
        ));
    }

    fn on_validation(&mut self, steps: usize, metrics: &ValidationMetrics, visuals: &[Visual]) {
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
        let drawn = self.draw_visuals(steps, visuals);
        self.keep_error(drawn);
        let curves = self.draw_curves();
        self.keep_error(curves);
    }
}

/// The lines of a JSONL log (a missing file has none; torn lines are skipped).
fn read_log(path: &Path) -> anyhow::Result<Vec<Value>> {
    match std::fs::read_to_string(path) {
        Ok(text) => Ok(text
            .lines()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
        Err(e) => Err(e).with_context(|| format!("cannot read {}", path.display())),
    }
}

/// `(step, value at path)` of every log line that has a number there.
fn series(lines: &[Value], name: &str, path: &[&str]) -> Series {
    let points = lines
        .iter()
        .filter_map(|line| {
            let step = line["step"].as_f64()?;
            let value = path.iter().try_fold(line, |v, key| v.get(key))?.as_f64()?;
            Some((step, value))
        })
        .collect();
    Series {
        name: name.to_string(),
        points,
    }
}
