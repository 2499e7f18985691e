//! Checkpoints and resumption: a run stopped and resumed takes the same
//! steps with the same losses as an uninterrupted one.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use mbs_train::RunConfig;
use mbs_train::checkpoint::Checkpoint;
use mbs_train::run::{End, Observer, Quiet, Start, TrainingRun};
use mbs_train::step::StepReport;
use serde_json::Value;

const STEPS: usize = 8;

fn config(overrides: &[&str]) -> RunConfig {
    let mut all: Vec<String> = vec![
        format!("trainer.lr.total_steps={STEPS}"),
        "trainer.lr.max_lr=0.002".into(),
        "trainer.ema_base=0.9".into(),
        "network.max_disparity=32".into(),
        "network.compact.features=8".into(),
        "network.compact.hidden=8".into(),
        "data.batch_size=2".into(),
        "data.crop_height=48".into(),
        "data.crop_width=96".into(),
        "augment.occlusion_min_side=8".into(),
        "augment.occlusion_max_side=16".into(),
        "log_every=1".into(),
        "val_every=4".into(),
        "checkpoint_every=100".into(),
        "seed=9".into(),
    ];
    all.extend(overrides.iter().map(|s| s.to_string()));
    RunConfig::layered(None, &all).unwrap()
}

/// Sets the stop flag after a given step, as Ctrl-C would.
struct StopAfter<'a> {
    step: usize,
    flag: &'a AtomicBool,
}

impl Observer for StopAfter<'_> {
    fn on_step(&mut self, report: &StepReport, _: f64) {
        if report.step + 1 == self.step {
            self.flag.store(true, Ordering::Relaxed);
        }
    }
}

fn log(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn field(lines: &[Value], key: &str) -> Vec<f64> {
    lines.iter().map(|l| l[key].as_f64().unwrap()).collect()
}

#[test]
fn a_stopped_and_resumed_run_matches_an_uninterrupted_one() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = common::synthesise(&dir.path().join("data"), 1, 128, 64);
    let straight = dir.path().join("straight");
    runs_to_the_end(&manifest, &straight, Start::Fresh);
    let resumed = dir.path().join("resumed");
    a_stopped_run_is_checkpointed(&manifest, &resumed);
    a_change_of_the_computation_is_refused_by_name(&manifest, &resumed);
    runs_to_the_end(&manifest, &resumed, Start::Resumed(3));
    training_logs_match(&straight, &resumed);
    validation_logs_match(&straight, &resumed);
}

/// Opens the run in `out` on `manifest`, which must start as `expected`
/// (a resumed one with its steps taken), and trains it to the end.
fn runs_to_the_end(manifest: &Path, out: &Path, expected: Start) {
    let (mut run, start) = TrainingRun::open(manifest, out, config(&[])).unwrap();
    assert_eq!(start, expected);
    if let Start::Resumed(steps) = expected {
        assert_eq!(run.steps_taken(), steps);
    }
    assert!(matches!(
        run.run(&mut Quiet, &AtomicBool::new(false)).unwrap(),
        End::Finished { .. }
    ));
}

/// A run in `out` stopped after step 3, as Ctrl-C would, saves a whole
/// checkpoint there.
fn a_stopped_run_is_checkpointed(manifest: &Path, out: &Path) {
    let stop = AtomicBool::new(false);
    let (mut run, _) = TrainingRun::open(manifest, out, config(&[])).unwrap();
    let end = run
        .run(
            &mut StopAfter {
                step: 3,
                flag: &stop,
            },
            &stop,
        )
        .unwrap();
    assert_eq!(end, End::Stopped(3));
    let checkpoint = Checkpoint::latest(out).unwrap().unwrap();
    assert_eq!(checkpoint.state.steps, 3);
    assert_eq!(checkpoint.state.rng.next_step, 3);
    for file in ["student.bpk", "teacher.bpk", "optimizer.bpk", "state.json"] {
        assert!(checkpoint.dir.join(file).is_file(), "{file}");
    }
}

/// A settings change that alters the computation of the checkpointed run
/// in `out` is refused by name.
fn a_change_of_the_computation_is_refused_by_name(manifest: &Path, out: &Path) {
    let refused = TrainingRun::open(manifest, out, config(&["trainer.loss.omega=3"]))
        .err()
        .unwrap()
        .to_string();
    assert!(
        refused.contains("trainer.loss.omega: 2.0 -> 3.0"),
        "{refused}"
    );
}

/// The `straight` and `resumed` runs logged the same steps with the same
/// figures, and how long each step waited for data.
fn training_logs_match(straight: &Path, resumed: &Path) {
    let (a, b) = (
        log(&straight.join("train.jsonl")),
        log(&resumed.join("train.jsonl")),
    );
    assert_eq!(
        field(&a, "step"),
        (1..=STEPS).map(|s| s as f64).collect::<Vec<_>>()
    );
    assert_eq!(field(&a, "step"), field(&b, "step"));
    // Every line says how long its steps waited for data (ms per step).
    for wait in field(&a, "data_wait_ms")
        .into_iter()
        .chain(field(&b, "data_wait_ms"))
    {
        assert!(wait.is_finite() && (0.0..60e3).contains(&wait), "{wait}");
    }
    for key in [
        "loss",
        "geometry",
        "photometric",
        "smoothness",
        "lr",
        "momentum",
    ] {
        for (step, (x, y)) in field(&a, key).iter().zip(field(&b, key)).enumerate() {
            assert!(
                (x - y).abs() <= 1e-4 * x.abs().max(1e-3),
                "{key} at step {}: {x} uninterrupted, {y} resumed",
                step + 1
            );
        }
    }
}

/// The `straight` and `resumed` runs validated at the same steps with the
/// same EPE.
fn validation_logs_match(straight: &Path, resumed: &Path) {
    let (a, b) = (
        log(&straight.join("val.jsonl")),
        log(&resumed.join("val.jsonl")),
    );
    assert_eq!(field(&a, "step"), vec![0.0, 4.0, 8.0]);
    assert_eq!(field(&a, "step"), field(&b, "step"));
    let epe = |lines: &[Value]| -> Vec<f64> {
        lines
            .iter()
            .map(|l| l["ALL"]["epe"].as_f64().unwrap())
            .collect()
    };
    for (x, y) in epe(&a).iter().zip(epe(&b)) {
        assert!((x - y).abs() <= 1e-3, "validation EPE {x} vs {y}");
    }
}

/// Truncates every training view once `step` steps are taken, as a disk
/// that goes bad mid-run would.
struct BreakViewsAfter {
    step: usize,
    views: Vec<std::path::PathBuf>,
}

impl Observer for BreakViewsAfter {
    fn on_step(&mut self, report: &StepReport, _: f64) {
        if report.step + 1 == self.step {
            for view in &self.views {
                std::fs::write(view, b"\x89PNG broken").unwrap();
            }
        }
    }
}

#[test]
fn a_broken_view_is_refused_before_the_first_step_or_checkpointed_after() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = common::synthesise(&dir.path().join("data"), 1, 128, 64);
    let parsed = mbs_dataset::Manifest::load(&manifest).unwrap();
    let views: Vec<std::path::PathBuf> = parsed
        .samples
        .iter()
        .filter(|s| s.split == mbs_dataset::Split::Train)
        .flat_map(|s| s.views.iter().map(|v| manifest.with_file_name(v)))
        .collect();

    // Broken before the start: refused by name, before any step.
    let first = views[0].clone();
    let intact = std::fs::read(&first).unwrap();
    std::fs::write(&first, &intact[..intact.len() / 2]).unwrap();
    let err = TrainingRun::open(&manifest, &dir.path().join("early"), config(&[]))
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("1 training view(s) cannot be used"), "{err}");
    assert!(err.contains(&first.display().to_string()), "{err}");
    std::fs::write(&first, &intact).unwrap();

    // Broken mid-run: the error ends the run, the steps taken are kept.
    let run_dir = dir.path().join("late");
    let never = AtomicBool::new(false);
    let (mut run, _) =
        TrainingRun::open(&manifest, &run_dir, config(&["trainer.lr.total_steps=60"])).unwrap();
    let mut observer = BreakViewsAfter { step: 2, views };
    let err = run.run(&mut observer, &never).unwrap_err().to_string();
    assert!(err.contains("rgb_"), "{err}");
    let taken = run.steps_taken();
    assert!((2..60).contains(&taken), "{taken}");
    let checkpoint = Checkpoint::latest(&run_dir).unwrap().unwrap();
    assert_eq!(checkpoint.state.steps, taken);
}
