//! The bad-input table: each class of hostile input (issue 12) run through
//! `mbs-tool` itself, with its exit status and message, and after every
//! case a check that nothing changed outside `--out`, no temporary file was
//! left in it and no command panicked (exit 101). Then two concurrent runs
//! into one folder, which must both succeed with the outputs of one run.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::{Path, PathBuf};

use common::{mbs_tool, text};
use mbs_core::FloatImage;
use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_test_support::files::tree;
use serde_json::{Value, json};

const W: u32 = 64;
const H: u32 = 48;

/// A textured view, shifted by `shift` pixels (a rectified pair).
fn view(shift: u32) -> image::RgbImage {
    image::RgbImage::from_fn(W, H, |x, y| {
        let v = (((x + shift) * 7919) ^ (y * 104_729)).wrapping_mul(2_654_435_761) >> 24;
        image::Rgb([v as u8, (v * 3) as u8, (255 - v) as u8])
    })
}

fn manifest(samples: Value, focal: f64) -> Value {
    json!({
        "format": "mbs-manifest/1",
        "name": "bad",
        "rig": {"num_views": 2, "baseline_m": 0.5, "focal_px": focal, "cx": 31.5, "cy": 23.5,
                "width": W, "height": H},
        "samples": samples
    })
}

fn sample(id: &str, views: [&str; 2]) -> Value {
    json!({"id": id, "split": "test", "views": views,
           "ground_truth": [{"reference": 0, "target": 1, "disparity": "gt.pfm"}]})
}

/// The input folder every case reads: two views, ground truth, broken
/// files and one manifest per class of bad manifest.
fn inputs(data: &Path) {
    std::fs::create_dir_all(data).unwrap();
    view(0).save(data.join("left.png")).unwrap();
    view(4).save(data.join("right.png")).unwrap();
    let gt = FloatImage::from_pixel(W, H, image::Luma([4.0]));
    write_pfm_grey(&data.join("gt.pfm"), &gt, Endian::Little).unwrap();
    let empty = FloatImage::from_pixel(W, H, image::Luma([f32::INFINITY]));
    write_pfm_grey(&data.join("empty_gt.pfm"), &empty, Endian::Little).unwrap();
    std::fs::write(
        data.join("huge.pfm"),
        b"Pf\n2147483648 2147483648\n-1.0\n\0\0\0\0",
    )
    .unwrap();
    std::fs::write(
        data.join("wrong_type.json"),
        br#"{"data": {"batch_size": "two"}}"#,
    )
    .unwrap();
    std::fs::create_dir_all(data.join("preds")).unwrap();
    write_pfm_grey(&data.join("preds/s0.pfm"), &gt, Endian::Little).unwrap();
    for (name, m) in manifests() {
        std::fs::write(data.join(name), m.to_string()).unwrap();
    }
}

/// The manifests of [`inputs`] by file name: a good one of two samples and
/// one per class of bad manifest.
fn manifests() -> [(&'static str, Value); 10] {
    let views = ["left.png", "right.png"];
    [
        (
            "ok.json",
            manifest(json!([sample("s0", views), sample("s1", views)]), 480.0),
        ),
        (
            "escape_id.json",
            manifest(json!([sample("../escape", views)]), 480.0),
        ),
        (
            "absolute_id.json",
            manifest(json!([sample("/tmp/escape", views)]), 480.0),
        ),
        (
            "escape_path.json",
            manifest(
                json!([sample("s0", ["../outside/a.png", "right.png"])]),
                480.0,
            ),
        ),
        (
            "duplicate.json",
            manifest(json!([sample("s0", views), sample("s0", views)]), 480.0),
        ),
        ("focal.json", manifest(json!([sample("s0", views)]), -5.0)),
        ("empty_gt.json", {
            let mut m = manifest(json!([sample("s0", views)]), 480.0);
            m["samples"][0]["ground_truth"][0]["disparity"] = json!("empty_gt.pfm");
            m
        }),
        ("huge_gt.json", {
            let mut m = manifest(json!([sample("s0", views)]), 480.0);
            m["samples"][0]["ground_truth"][0]["disparity"] = json!("huge.pfm");
            m
        }),
        ("float_target.json", {
            let mut m = manifest(json!([sample("s0", ["left.png", "missing.png"])]), 480.0);
            m["samples"][0]["ground_truth"][0]["target"] = json!(1.0);
            m
        }),
        ("escape_depth.json", {
            let mut m = manifest(json!([sample("s0", views)]), 480.0);
            m["depth"] = json!({"encoding": "carla-rgb", "camera": 0, "max_depth_m": 100.0});
            m["samples"][0]["depth"] = json!("../outside/depth_0.png");
            m
        }),
    ]
}

/// One row of the table: arguments (`{d}` = the input folder, `{o}` = the
/// output folder), the exit status and a piece of the message.
struct Case {
    args: &'static str,
    status: i32,
    message: &'static str,
}

const fn case(args: &'static str, status: i32, message: &'static str) -> Case {
    Case {
        args,
        status,
        message,
    }
}

/// Usage errors exit 2 (before any work), failures 1.
const CASES: &[Case] = &[
    // 1. Sizes from headers and flags.
    case(
        "eval {d}/huge.pfm --gt {d}/gt.pfm",
        1,
        "huge.pfm: image size 2147483648x2147483648 is beyond the limit",
    ),
    case(
        "extrapolate --left {d}/left.png --right {d}/right.png --left-disparity {d}/huge.pfm --out {o}",
        1,
        "beyond the limit",
    ),
    case("validate {d}/huge_gt.json", 1, "beyond the limit"),
    case(
        "synth --out {o} --width 100000 --height 100000",
        2,
        "from 1 to 32768",
    ),
    case("synth --out {o} --jobs 100000", 2, "from 0 to 1024"),
    case("scan {d} --views 100000000", 2, "from 2 to 64"),
    case("synth --out {o} --supersample 1000", 2, "from 1 to 8"),
    // 2. Paths and ids that would leave their roots.
    case(
        "predict --manifest {d}/escape_id.json --out {o}",
        1,
        "/samples/0/id",
    ),
    case(
        "predict --manifest {d}/absolute_id.json --out {o}",
        1,
        "/samples/0/id",
    ),
    case(
        "decode-depth {d}/escape_depth.json --out {o}",
        1,
        "/samples/0/depth",
    ),
    case("synth --out {o} --towns ../../x", 2, "is not a folder name"),
    case("validate {d}/escape_path.json", 1, "/samples/0/views/0"),
    case("validate {d}/escape_id.json", 1, "/samples/0/id"),
    // 3. Schema and model agree; validate never calls unchecked files clean.
    case(
        "validate {d}/float_target.json --deep",
        1,
        "missing.png: missing file",
    ),
    case("validate {d}/duplicate.json", 1, "duplicate sample id"),
    case(
        "predict --manifest {d}/duplicate.json --out {o}",
        1,
        "sample id \"s0\" appears more than once",
    ),
    case(
        "eval {d}/preds --manifest {d}/duplicate.json",
        1,
        "appears more than once",
    ),
    // 4. Bad values.
    case(
        "predict --manifest {d}/focal.json --out {o}",
        1,
        "/rig/focal_px",
    ),
    case(
        "extrapolate --left {d}/left.png --right {d}/right.png --out {o} --focal 0",
        2,
        "not a finite number above 0",
    ),
    case(
        "decode-depth {d} --out {o} --max-depth NaN",
        2,
        "not a finite number above 0",
    ),
    case(
        "eval {d}/gt.pfm --gt {d}/gt.pfm --gt-scale 0",
        2,
        "not a finite number above 0",
    ),
    case(
        "eval {d}/gt.pfm --gt {d}/gt.pfm --gt-scale -4",
        2,
        "not a finite number above 0",
    ),
    case(
        "eval {d}/gt.pfm --gt {d}/gt.pfm --gt-scale NaN",
        2,
        "not a finite number above 0",
    ),
    case(
        "eval {d}/gt.pfm --gt {d}/gt.pfm --thresholds -1,NaN",
        2,
        "not a finite number above 0",
    ),
    case(
        "eval {d}/gt.pfm --gt {d}/empty_gt.pfm",
        1,
        "empty_gt.pfm: the ground truth has no valid pixel",
    ),
    // 5. One bad item does not hide the others.
    case(
        "eval {d}/preds --manifest {d}/ok.json",
        1,
        "no prediction s1.pfm, .png or .exr",
    ),
    // 7. Clear messages.
    case(
        "predict --left {d} --right {d}/right.png --out {o}",
        1,
        "is a folder, the left view must be a file",
    ),
    case(
        "eval {d} --gt {d}/gt.pfm",
        1,
        "is a folder, expected a float map file",
    ),
    case(
        "extrapolate --left {d}/left.png --right {d} --out {o}",
        1,
        "is a folder, the right view must be a file",
    ),
    case(
        "predict --left {d}/left.png --right {d}/right.png --out {d}/gt.pfm",
        1,
        "exists and is not a folder",
    ),
    // 8. One meaning per flag, one exit code per kind of error (issue 26).
    case(
        "predict --left {d}/left.png --right {d}/right.png --out {o} --device bogus",
        2,
        "bogus",
    ),
    case(
        "eval {d}/preds --manifest {d}/ok.json --device bogus",
        2,
        "bogus",
    ),
    case("train {d}/ok.json --out {o} --device cpu,bogus", 2, "bogus"),
    case(
        "train {d}/ok.json --out {o} --precision f8",
        2,
        "unknown precision `f8`; expected f32, bf16 or f16",
    ),
    case(
        "train {d}/ok.json --out {o} --backbone resnet",
        2,
        "unknown backbone `resnet`",
    ),
    case(
        "predict --left {d}/left.png --right {d}/right.png --out {o} --device cuda",
        1,
        "the built-in matcher runs on the CPU",
    ),
    case(
        "predict --left {d}/left.png --right {d}/right.png --out {o} --max-disparity 100000",
        2,
        "not an integer from 0 to 4096",
    ),
    case(
        "train {d}/ok.json --out {o} --config {d}/wrong_type.json --batch-size 2",
        1,
        "the configuration file: /data/batch_size",
    ),
    // A run the machine's memory cannot hold is refused before anything
    // is allocated or written (issue 26, item 1): about 800 TiB here.
    case(
        "train {d}/ok.json --out {o} --backbone raft-stereo --batch-size 1024 --crop 4096x4096",
        1,
        "more than twice this machine's",
    ),
];

#[test]
fn every_bad_input_is_refused_clearly_and_writes_nothing_outside_out() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    inputs(&data);
    std::fs::create_dir_all(dir.path().join("outside")).unwrap();
    let out = dir.path().join("out");
    let before = tree(dir.path());
    for case in CASES {
        let args: Vec<String> = case
            .args
            .split(' ')
            .map(|a| {
                a.replace("{d}", &data.display().to_string())
                    .replace("{o}", &out.display().to_string())
            })
            .collect();
        let output = mbs_tool().args(&args).output().unwrap();
        let all = format!(
            "{}{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        );
        let report = format!("`{}`\n{}", case.args, text(&output));
        assert_eq!(output.status.code(), Some(case.status), "{report}");
        assert!(
            all.contains(case.message),
            "expected {:?} in {report}",
            case.message
        );
        assert!(!all.contains("panicked"), "{report}");
        let partials: Vec<PathBuf> = tree(&out)
            .into_iter()
            .map(|(p, _)| p)
            .filter(|p| p.to_string_lossy().ends_with(".partial"))
            .collect();
        assert!(partials.is_empty(), "{partials:?} left by {report}");
        if out.exists() {
            std::fs::remove_dir_all(&out).unwrap();
        }
        assert_eq!(
            tree(dir.path()),
            before,
            "files changed outside --out by {report}"
        );
    }
    // The scored image is in the table although the other had no prediction.
    let output = mbs_tool()
        .arg("eval")
        .arg(data.join("preds"))
        .arg("--manifest")
        .arg(data.join("ok.json"))
        .output()
        .unwrap();
    assert!(
        String::from_utf8_lossy(&output.stdout).contains("s0"),
        "{}",
        text(&output)
    );
}

/// Two runs started at once into one folder (issue 57): one writes, the
/// other is refused at once unless the first has already finished (then it
/// skips the finished outputs); either way the folder ends with the
/// outputs of one run, and a run after them completes it.
#[test]
fn two_runs_into_one_folder_one_at_a_time_with_the_outputs_of_one() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    inputs(&data);
    let views = ["left.png", "right.png"];
    let samples: Vec<Value> = (0..8).map(|i| sample(&format!("s{i}"), views)).collect();
    let many = data.join("many.json");
    std::fs::write(&many, manifest(Value::Array(samples), 480.0).to_string()).unwrap();
    let predict = |out: &Path| {
        let mut command = mbs_tool();
        command
            .args([
                "predict",
                "--max-disparity",
                "16",
                "--jobs",
                "1",
                "--manifest",
            ])
            .arg(&many)
            .arg("--out")
            .arg(out);
        command
    };
    let reference = dir.path().join("reference");
    let single = predict(&reference).output().unwrap();
    assert!(single.status.success(), "{}", text(&single));

    let shared = dir.path().join("shared");
    let quiet = |mut command: std::process::Command| {
        command
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let first = quiet(predict(&shared));
    let second = quiet(predict(&shared));
    let mut succeeded = 0;
    for run in [first, second] {
        let output = run.wait_with_output().unwrap();
        match output.status.success() {
            true => succeeded += 1,
            false => assert!(text(&output).contains("is in use by"), "{}", text(&output)),
        }
    }
    assert!(succeeded >= 1, "neither run wrote");
    let last = predict(&shared).output().unwrap();
    assert!(last.status.success(), "{}", text(&last));
    assert_eq!(tree(&shared), tree(&reference));
}

/// Outputs that are not regular files (issue 43): `scan --out` onto a
/// character device, a FIFO, a socket or a folder is refused, naming it,
/// and leaves it as it was; so is `--shard auto` in a SLURM array task
/// whose id lies outside its array (it would run another task's shard),
/// before anything is written.
#[cfg(unix)]
#[test]
fn special_files_as_outputs_and_array_tasks_outside_their_array_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let set = dir.path().join("set");
    let output = tiny_synth(&set).output().unwrap();
    assert!(output.status.success(), "{}", text(&output));
    scan_refuses_special_files_as_outputs(dir.path(), &set);
    array_tasks_outside_their_array_are_refused(dir.path());
}

/// `synth` of a tiny two-frame set into `out`.
#[cfg(unix)]
fn tiny_synth(out: &Path) -> std::process::Command {
    let mut command = mbs_tool();
    command.args([
        "synth",
        "--frames",
        "2",
        "--towns",
        "Town01",
        "--weathers",
        "ClearNoon",
    ]);
    command.args([
        "--width",
        "32",
        "--height",
        "16",
        "--focal",
        "16",
        "--no-checksums",
    ]);
    command.arg("--out").arg(out);
    command
}

/// `scan SET --out` onto each special file made in `dir` is refused,
/// naming it, and leaves it as it was; no temporary file is left in `dir`.
#[cfg(unix)]
fn scan_refuses_special_files_as_outputs(dir: &Path, set: &Path) {
    use mbs_test_support::special::{identity, special_files};
    let special = special_files(dir, "json");
    for file in &special {
        let before = identity(&file.path);
        let output = mbs_tool()
            .arg("scan")
            .arg(set)
            .arg("--out")
            .arg(&file.path)
            .output()
            .unwrap();
        let report = text(&output);
        assert_eq!(output.status.code(), Some(1), "{report}");
        assert!(file.is_refused_in(&report), "{report}");
        assert_eq!(identity(&file.path), before, "{report}");
    }
    let partials: Vec<PathBuf> = tree(dir)
        .into_iter()
        .map(|(p, _)| p)
        .filter(|p| p.to_string_lossy().ends_with(".partial"))
        .collect();
    assert!(partials.is_empty(), "{partials:?}");
}

/// `synth --shard auto` in a SLURM array task whose id lies outside its
/// array (it would run another task's shard) is a usage error naming the
/// variable that rules it out, before anything is written under `dir`.
#[cfg(unix)]
fn array_tasks_outside_their_array_are_refused(dir: &Path) {
    for (id, min, step, count, named) in [
        ("1", "3", "1", "2", "SLURM_ARRAY_TASK_MIN=3"),
        ("5", "3", "1", "2", "SLURM_ARRAY_TASK_COUNT=2"),
        ("3", "0", "2", "4", "SLURM_ARRAY_TASK_STEP=2"),
    ] {
        let out = dir.join(format!("shard-{id}"));
        let output = tiny_synth(&out)
            .args(["--shard", "auto"])
            .env("SLURM_ARRAY_TASK_ID", id)
            .env("SLURM_ARRAY_TASK_MIN", min)
            .env("SLURM_ARRAY_TASK_STEP", step)
            .env("SLURM_ARRAY_TASK_COUNT", count)
            .output()
            .unwrap();
        let report = text(&output);
        assert_eq!(output.status.code(), Some(2), "{report}");
        assert!(
            report.contains(&format!(
                "SLURM_ARRAY_TASK_ID={id} is not a task of the array"
            )) && report.contains(named),
            "{report}"
        );
        assert!(!out.exists(), "{report}");
    }
}
