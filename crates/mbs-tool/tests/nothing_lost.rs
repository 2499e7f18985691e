//! Nothing the user owns is lost (issue 50), through `mbs-tool` itself:
//! an output that would replace an input is refused before anything is
//! written, a FIFO where a file belongs is named instead of read for ever,
//! and `train` checks every flag before it removes a checkpoint or touches
//! a log.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{mbs_tool, refused, text, within};
use mbs_core::FloatImage;
use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_test_support::files::tree;

const W: u32 = 48;
const H: u32 = 32;

/// A MiddEval3 split folder `root/trainingQ` of one scene, `Scene`, with
/// views, ground truth, its mask and calib.txt; returns the split.
fn middlebury(root: &Path) -> PathBuf {
    let split = root.join("trainingQ");
    let scene = split.join("Scene");
    std::fs::create_dir_all(&scene).unwrap();
    let view = |shift: u32| {
        image::RgbImage::from_fn(W, H, |x, y| {
            let v = (((x + shift) * 7919) ^ (y * 104_729)).wrapping_mul(2_654_435_761) >> 24;
            image::Rgb([v as u8, (v * 5) as u8, (255 - v) as u8])
        })
    };
    view(3).save(scene.join("im0.png")).unwrap();
    view(0).save(scene.join("im1.png")).unwrap();
    let gt = FloatImage::from_pixel(W, H, image::Luma([3.0]));
    write_pfm_grey(&scene.join("disp0GT.pfm"), &gt, Endian::Little).unwrap();
    image::GrayImage::from_pixel(W, H, image::Luma([255]))
        .save(scene.join("mask0nocc.png"))
        .unwrap();
    std::fs::write(scene.join("calib.txt"), "ndisp=16\n").unwrap();
    split
}

/// `submit --name GT --out M` used to write `disp0GT.pfm` over every
/// scene's ground truth; `benchmark --per-image` over an input it reads.
#[test]
fn outputs_never_replace_the_inputs_of_submit_or_benchmark() {
    let dir = tempfile::tempdir().unwrap();
    let split = middlebury(dir.path());
    let gt = split.join("Scene/disp0GT.pfm");
    let truth = std::fs::read(&gt).unwrap();
    let before = tree(dir.path());
    let split_arg = split.to_str().unwrap();
    let out_arg = dir.path().to_str().unwrap();
    for name in ["GT", "gt"] {
        let output = mbs_tool()
            .args(["submit", "--middlebury", split_arg, "--name", name])
            .args(["--out", out_arg])
            .output()
            .unwrap();
        refused(&output, &["ground truth", "disp0"]);
    }
    for input in ["disp0GT.pfm", "im1.png", "calib.txt", "mask0nocc.png"] {
        let target = split.join("Scene").join(input);
        let output = mbs_tool()
            .args(["benchmark", "--middlebury", split_arg, "--per-image"])
            .arg(&target)
            .output()
            .unwrap();
        refused(&output, &[input, "refusing to replace an input"]);
    }
    assert_eq!(tree(dir.path()), before, "an input changed");
    // The MiddEval3 kit's own layout, results beside the data, works.
    let output = mbs_tool()
        .args(["submit", "--middlebury", split_arg, "--name", "MBS"])
        .args(["--out", out_arg])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", text(&output));
    assert!(split.join("Scene/disp0MBS.pfm").is_file());
    assert_eq!(std::fs::read(&gt).unwrap(), truth);
}

/// A `calib.txt` that is a FIFO used to hang every command that lists a
/// Middlebury folder; now each names it at once.
#[test]
fn a_fifo_where_a_file_belongs_is_named_not_read_for_ever() {
    let dir = tempfile::tempdir().unwrap();
    let split = middlebury(dir.path());
    let calib = split.join("Scene/calib.txt");
    std::fs::remove_file(&calib).unwrap();
    let made = Command::new("mkfifo").arg(&calib).status().unwrap();
    assert!(made.success());
    let split_arg = split.to_str().unwrap();
    let out = dir.path().join("out");
    let commands: [&[&str]; 3] = [
        &["benchmark", "--middlebury", split_arg],
        &["eval", "--middlebury", split_arg],
        &["predict", "--middlebury", split_arg, "--out"],
    ];
    for args in commands {
        let mut command = mbs_tool();
        command.args(args);
        if args[0] == "predict" {
            command.arg(&out);
        }
        let output = within(command, 60);
        refused(&output, &["calib.txt", "FIFO", "not a regular file"]);
    }
    assert!(!out.exists(), "predict wrote before it failed");
}

/// A MiddEval3 scene without `im1.png` used to be left out of the
/// submission archive, `submit` exiting 0; now the listing stops it
/// before anything is written, naming the scene and the file. A FIFO
/// where a finished output would be (the resume check decodes it) is
/// named at once, not read for ever.
#[test]
fn submit_names_a_scene_without_a_view_and_a_fifo_output() {
    let dir = tempfile::tempdir().unwrap();
    let split = middlebury(dir.path());
    let other = split.join("Other");
    std::fs::create_dir_all(&other).unwrap();
    for file in ["im0.png", "disp0GT.pfm", "mask0nocc.png", "calib.txt"] {
        std::fs::copy(split.join("Scene").join(file), other.join(file)).unwrap();
    }
    let before = tree(dir.path());
    let out = dir.path().join("out");
    let submit = || {
        let mut command = mbs_tool();
        command
            .args(["submit", "--middlebury", split.to_str().unwrap()])
            .args(["--name", "MBS", "--max-disparity", "16", "--out"])
            .arg(&out);
        within(command, 120)
    };
    let output = submit();
    let missing = other.join("im1.png").display().to_string();
    refused(
        &output,
        &[&missing, "scene Other has im0.png but not im1.png"],
    );
    assert!(!out.exists(), "submit wrote before it failed");
    assert_eq!(tree(dir.path()), before, "an input changed");

    std::fs::remove_dir_all(&other).unwrap();
    let fifo = out.join("trainingQ/Scene/disp0MBS.pfm");
    std::fs::create_dir_all(fifo.parent().unwrap()).unwrap();
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let output = submit();
    refused(&output, &[&fifo.display().to_string(), "FIFO"]);
}

/// A synthetic training set, as `train`'s own tests make it.
fn training_set(root: &Path) -> String {
    common::synth(root)
}

/// Trains a few steps of the compact network into `out` with `extra`
/// flags.
fn train(manifest: &str, out: &Path, extra: &[&str]) -> Output {
    let mut command = mbs_tool();
    command
        .args(["train", manifest, "--out"])
        .arg(out)
        .args(common::SMALL)
        .args([
            "--steps",
            "2",
            "--val-every",
            "100",
            "--checkpoint-every",
            "2",
        ])
        .args(extra);
    within(command, 300)
}

/// `train --restart --init nowhere` used to delete the run's checkpoints
/// before refusing `--init`; a bad `--init` file the same. A log that is a
/// FIFO is refused, not replaced.
#[test]
fn train_checks_before_it_removes_or_writes() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = training_set(&dir.path().join("data"));
    let run = dir.path().join("run");
    let first = train(&manifest, &run, &[]);
    assert!(first.status.success(), "{}", text(&first));
    let checkpoints = run.join("checkpoints");
    let kept = tree(&checkpoints);
    assert!(!kept.is_empty());
    let garbage = dir.path().join("garbage.pth");
    std::fs::write(&garbage, b"not a checkpoint").unwrap();
    // --restart would remove the checkpoint --init names.
    let own = run.join("checkpoints/step-0000002");
    assert!(own.is_dir());
    for init in [dir.path().join("nowhere"), garbage, own, run.clone()] {
        let output = train(
            &manifest,
            &run,
            &["--restart", "--init", init.to_str().unwrap()],
        );
        refused(&output, &[init.file_name().unwrap().to_str().unwrap()]);
        assert_eq!(
            tree(&checkpoints),
            kept,
            "checkpoints removed before a refusal"
        );
    }
    // More devices than batch items is a usage error (exit 2), refused
    // before the folder is touched.
    let shared = dir.path().join("shared");
    let output = train(&manifest, &shared, &["--device", "cpu,cpu,cpu"]);
    refused(&output, &["batch_size 2 is smaller than the 3 devices"]);
    assert_eq!(output.status.code(), Some(2), "{}", text(&output));
    assert!(!shared.exists());
    let fresh = dir.path().join("fresh");
    std::fs::create_dir_all(&fresh).unwrap();
    let log = fresh.join("train.jsonl");
    assert!(Command::new("mkfifo").arg(&log).status().unwrap().success());
    let output = train(&manifest, &fresh, &[]);
    refused(&output, &["train.jsonl", "FIFO", "not a regular file"]);
    use std::os::unix::fs::FileTypeExt;
    assert!(
        std::fs::symlink_metadata(&log)
            .unwrap()
            .file_type()
            .is_fifo()
    );
}
