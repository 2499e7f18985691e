//! What a run shows besides its logs: contact sheets of the validation
//! pairs (`visuals/step-N/`), the loss and validation curves (`loss.png`,
//! `val.png`), and TensorBoard event files (`tensorboard/`) with every
//! logged number and the contact sheets.

use std::path::{Path, PathBuf};

use mbs_core::FloatImage;
use mbs_core::atomic::write_bytes_atomic;
use mbs_core::formats::rgb::rgb_png_bytes;
use mbs_viz::{
    Key, LineChart, Panel, Series, colorize_disparity, labelled_row, weight_map_image,
    weight_map_key,
};
use serde_json::Value;

use super::Visual;
use super::logs::{TRAIN_LOG, VAL_LOG, read_log, validation_protocol};
use crate::error::TrainError;
use crate::losses::Term;
use crate::tensorboard::EventWriter;

/// The curves of a run.
pub const LOSS_PLOT: &str = "loss.png";
/// The validation curves of a run.
pub const VAL_PLOT: &str = "val.png";
/// Folder of the contact sheets.
pub const VISUALS_DIR: &str = "visuals";
/// Folder of the TensorBoard event files.
pub const TENSORBOARD_DIR: &str = "tensorboard";

/// The sheets, curves and events of one run.
pub(crate) struct RunReport {
    out: PathBuf,
    max_disparity: f32,
    /// Created with the first event, so a run that logs nothing (already
    /// complete) leaves no empty event file.
    events: Option<EventWriter>,
    /// Steps taken before this session, for a resumed run.
    resumed_after: Option<usize>,
}

/// The numbers of a log line as `(prefix/key, value)`, nested objects
/// joined with `/` (`val/ALL/out3`); `step` itself is left out.
fn scalars(prefix: &str, value: &Value, out: &mut Vec<(String, f32)>) {
    match value {
        Value::Object(map) => {
            for (key, v) in map {
                if prefix.is_empty() && key == "step" {
                    continue;
                }
                let tag = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}/{key}")
                };
                scalars(&tag, v, out);
            }
        }
        Value::Number(n) => {
            if let Some(v) = n.as_f64() {
                out.push((prefix.to_string(), v as f32));
            }
        }
        _ => {}
    }
}

impl RunReport {
    /// The report of the run in `out`; its events go to a new file in
    /// `out/tensorboard/`. A run resumed after `resumed_after` steps starts
    /// its file with a session start at the next logged step, so that
    /// TensorBoard drops what a killed session logged past its checkpoint.
    pub fn new(out: &Path, max_disparity: f32, resumed_after: Option<usize>) -> Self {
        Self {
            out: out.to_path_buf(),
            max_disparity,
            events: None,
            resumed_after,
        }
    }

    /// The run's event file, created on first use.
    fn events(&mut self) -> Result<&mut EventWriter, TrainError> {
        match &mut self.events {
            Some(events) => Ok(events),
            slot => {
                let mut events = EventWriter::create(&self.out.join(TENSORBOARD_DIR))?;
                if let Some(steps) = self.resumed_after {
                    // Steps are logged 1-based: the first new one is steps + 1.
                    events.session_start(steps as u64 + 1)?;
                }
                Ok(slot.insert(events))
            }
        }
    }

    /// Logs the numbers of a log line under `group/` (e.g. `train/loss`).
    pub fn log_line(&mut self, group: &str, line: &Value) -> Result<(), TrainError> {
        let step = line["step"].as_u64().unwrap_or(0);
        let mut values = Vec::new();
        scalars("", line, &mut values);
        let events = self.events()?;
        for (tag, value) in values {
            events.scalar(&format!("{group}/{tag}"), step, value)?;
        }
        events.flush()
    }

    /// Draws the contact sheet of each visual into `visuals/step-N/` and
    /// logs it as a TensorBoard image: reference | teacher | student | GT
    /// | weight map, each under its caption, and below them the colour bar
    /// of the disparities (one scale, 0 to the network's maximum) and the
    /// key to the weight map's colours.
    pub fn visuals(&mut self, steps: usize, visuals: &[Visual]) -> Result<(), TrainError> {
        let dir = self.out.join(VISUALS_DIR).join(format!("step-{steps:07}"));
        for (i, visual) in visuals.iter().enumerate() {
            let colour = |map: &FloatImage| colorize_disparity(map, self.max_disparity);
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
            let panels = [
                Panel::new(&visual.reference, "reference"),
                Panel::new(&teacher, "teacher disparity (px)"),
                Panel::new(&student, "student disparity (px)"),
                Panel::new(&gt, "ground truth (px)"),
                Panel::new(&weights, "weight map"),
            ];
            let scale = Key::DisparityBar {
                title: "disparity of teacher, student and ground truth (px)".into(),
                max: self.max_disparity,
            };
            let sheet = labelled_row(&panels, &[scale, weight_map_key()])?;
            let name: String = visual
                .name
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
                .collect();
            let path = dir.join(format!("{i:02}_{name}.png"));
            let png = rgb_png_bytes(&sheet).map_err(|e| TrainError::data(&path, e))?;
            write_bytes_atomic(&path, &png)?;
            let tag = format!("val/{i:02}_{name}");
            self.events()?
                .image(&tag, steps as u64, sheet.dimensions(), &png)?;
        }
        self.events()?.flush()
    }

    /// Redraws `loss.png` and `val.png` from the logs.
    pub fn curves(&self) -> Result<(), TrainError> {
        let train = read_log(&self.out.join(TRAIN_LOG))?;
        let losses: Vec<Series> = std::iter::once("loss")
            .chain(Term::ALL.map(Term::name))
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
            // Beside the scores, how much the training steps were
            // supervised: a collapse shows as the masks falling to 0 (and
            // the warps leaving the image) while Out-3 rises.
            let supervision = [
                ("student mask (training)", "student_mask"),
                ("teacher mask (training)", "teacher_mask"),
                ("warps leaving the image (training)", "outside"),
            ]
            .iter()
            .map(|(name, key)| percent(series(&train, name, &["supervision", key])))
            .filter(|s| !s.points.is_empty());
            // The protocol of the last validation.
            let protocol = val.last().map_or("pixels", validation_protocol);
            LineChart {
                title: format!(
                    "Teacher Out-3 ({protocol} protocol) on held-out pairs, and the supervision \
                     of training"
                ),
                x_label: "training step".into(),
                y_label: "% of pixels".into(),
                log_y: false,
                series: out3.into_iter().chain(supervision).collect(),
            }
            .write_png(&self.out.join(VAL_PLOT))?;
        }
        Ok(())
    }
}

/// A series of shares (0 to 1) in percent.
fn percent(mut series: Series) -> Series {
    series.points.iter_mut().for_each(|(_, v)| *v *= 100.0);
    series
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_lines_become_tagged_scalars() {
        let line = serde_json::json!({
            "step": 40,
            "loss": 0.5,
            "geometry": null,
            "ALL": {"epe": 1.25, "out3": 4.0},
        });
        let mut values = Vec::new();
        scalars("", &line, &mut values);
        values.sort_by(|a, b| a.0.cmp(&b.0));
        assert_eq!(
            values,
            [
                ("ALL/epe".to_string(), 1.25),
                ("ALL/out3".to_string(), 4.0),
                ("loss".to_string(), 0.5)
            ]
        );
    }
}
