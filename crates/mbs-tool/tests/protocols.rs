//! `eval --protocol` and `benchmark --protocol` through the binary, on the
//! presets' test data (mbs-eval's tests/presets/fixture.rs: Teddy laid out
//! as each benchmark's folder): `eval --json` prints the library's JSON;
//! `--frames` and the frames without usable ground truth are named;
//! a frame without its non-occluded ground truth fails, named; `benchmark`
//! scores under s3 by default and any preset on request. The presets'
//! figures themselves are tested on the library (mbs-eval's
//! tests/presets.rs).

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;
#[path = "../../mbs-eval/tests/presets/fixture.rs"]
mod fixture;

use std::path::Path;

use common::{run, text};
use fixture::*;
use mbs_core::formats::read_disparity;
use mbs_dataset::pairs::PairSource;
use mbs_eval::{Protocol, rules_for, score_predictions};
use serde_json::Value;

/// `eval PREDICTIONS FLAG DIR --protocol PRESET --json` and its output.
fn eval(layout: &Layout, predictions: &Path, preset: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "eval",
        predictions.to_str().unwrap(),
        layout.flag,
        layout.dir.to_str().unwrap(),
        "--protocol",
        preset,
        "--json",
    ];
    args.extend_from_slice(extra);
    run(&args)
}

/// `--frames` keeps the frames it names (blank lines and comments
/// ignored), a listed frame that is nowhere is an error naming it, and the
/// frames without usable ground truth (no file, a folder, a FIFO) are
/// named in a warning and in the JSON.
#[test]
fn frame_lists_keep_their_frames_and_frames_without_truth_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let kitti = kitti_layout(dir.path(), 2015);
    let output = eval(&kitti, &kitti.predictions, "s3", &[]);
    assert!(output.status.success(), "{}", text(&output));
    let json: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(
        json["unscored"],
        serde_json::json!(["000002_10", "000003_10"])
    );
    assert!(
        String::from_utf8_lossy(&output.stderr).contains(
            "2 frame(s) not scored, without usable ground truth (missing, or not a regular \
             file): 000002_10, 000003_10"
        ),
        "{}",
        text(&output)
    );

    let list = dir.path().join("list.txt");
    std::fs::write(
        &list,
        "# KITTI 2015, one frame\n\n000001_10  # Teddy x4\n000002_10\n",
    )
    .unwrap();
    let frames = ["--frames", list.to_str().unwrap()];
    let output = eval(&kitti, &kitti.predictions, "s3", &frames);
    assert!(output.status.success(), "{}", text(&output));
    let json: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(json["images"].as_array().map(Vec::len), Some(1));
    assert_eq!(json["images"][0]["name"], "000001_10");
    assert_eq!(json["unscored"], serde_json::json!(["000002_10"]));
    let want = s3(&kitti.frames[1..], 3.0);
    assert!(agree(&reported(&json, "s3", ""), &want));

    std::fs::write(&list, "000001_10\n000009_10\n").unwrap();
    let output = eval(&kitti, &kitti.predictions, "s3", &frames);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(
        text(&output).contains("list.txt: 1 listed frame(s) not found in")
            && text(&output).contains("kitti2015/training: 000009_10"),
        "{}",
        text(&output)
    );

    let middlebury = middlebury_layout(dir.path());
    let output = eval(&middlebury, &middlebury.predictions, "pixels", &[]);
    assert!(output.status.success(), "{}", text(&output));
    let json: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(json["unscored"], serde_json::json!(["Fifo", "NoTruth"]));
}

/// A frame whose non-occluded ground truth is missing (KITTI's
/// `disp_noc_0` file, a Middlebury or ETH3D `mask0nocc.png`) while the
/// other frames have theirs used to be scored in ALL and left out of NOC
/// and OCC without a word, so that NOC and ALL were figures over different
/// frames. Now `eval` and `benchmark` name the frame and the missing file,
/// count the frame as failed and exit 1, scoring the others; a mask that
/// does not decode is named too; no input changes.
#[test]
fn a_frame_without_its_noc_ground_truth_is_named_not_left_out_of_noc() {
    let dir = tempfile::tempdir().unwrap();
    let layouts = [
        kitti_layout(dir.path(), 2015),
        middlebury_layout(dir.path()),
        eth3d_layout(dir.path()),
    ];
    let masks = [
        layouts[0].dir.join("disp_noc_0/000001_10.png"),
        layouts[1].dir.join("Teddy4/mask0nocc.png"),
        dir.path().join("two_view_training_gt/teddy4/mask0nocc.png"),
    ];
    for mask in &masks {
        std::fs::remove_file(mask).unwrap();
    }
    let before = mbs_test_support::files::tree(dir.path());
    let mut folders = Vec::new();
    for (layout, mask) in layouts.iter().zip(&masks) {
        let output = eval(layout, &layout.predictions, "pixels", &[]);
        let named = format!(
            "{}: {}: no such file",
            layout.frames[1].name,
            mask.display()
        );
        assert_eq!(output.status.code(), Some(1), "{}", text(&output));
        assert!(text(&output).contains(&named), "{named}: {}", text(&output));
        let json: Value = serde_json::from_slice(&output.stdout).unwrap();
        assert_eq!(json["images"].as_array().map(Vec::len), Some(1));
        folders.extend([layout.flag, layout.dir.to_str().unwrap()]);
    }
    let output = run(&[
        &["benchmark", "--max-disparity", "16", "--json"],
        &folders[..],
    ]
    .concat());
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    let json: Value = serde_json::from_slice(&output.stdout).unwrap();
    for (column, mask) in masks.iter().enumerate() {
        assert_eq!(json["benchmarks"][column]["failed"], 1, "{json:#}");
        assert!(text(&output).contains(&mask.display().to_string()));
    }
    assert_eq!(mbs_test_support::files::tree(dir.path()), before);

    std::fs::write(&masks[1], b"not a PNG").unwrap();
    let output = eval(&layouts[1], &layouts[1].predictions, "pixels", &[]);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    let named = format!("Teddy4: {}", masks[1].display());
    assert!(text(&output).contains(&named), "{named}: {}", text(&output));
}

/// `predict FLAG DIR` with the built-in matcher over 64 disparities into
/// `out`, read back into `layout`'s frames (the predictions `benchmark`
/// makes of the same pairs).
fn predict_into(layout: &mut Layout, out: &Path) {
    let output = run(&[
        "predict",
        layout.flag,
        layout.dir.to_str().unwrap(),
        "--max-disparity",
        "64",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", text(&output));
    for f in &mut layout.frames {
        f.pred = read_disparity(&out.join(format!("{}.pfm", f.name)), None).unwrap();
    }
}

/// `benchmark` scores under s3 unless told otherwise and names the
/// protocol: its OCC, NOC and ALL equal the s3 computation here on the
/// predictions `predict` makes; `--protocol pixels` gives the pooled
/// figures; `--protocol kitti` D1 on KITTI 2015 (only the frame a
/// `DIR=FILE` list names) and Out-3 on KITTI 2012; a shared list naming a
/// frame of no folder stops it.
#[test]
fn benchmark_scores_under_s3_by_default_and_any_preset_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let mut kitti15 = kitti_layout(dir.path(), 2015);
    let mut driving = driving_stereo_layout(dir.path());
    predict_into(&mut kitti15, &dir.path().join("sgm-kitti"));
    predict_into(&mut driving, &dir.path().join("sgm-driving"));
    let benchmark = |extra: &[&str]| {
        let mut args = vec!["benchmark", "--max-disparity", "64", "--json"];
        args.extend_from_slice(extra);
        let output = run(&args);
        assert!(output.status.success(), "{}", text(&output));
        serde_json::from_slice::<Value>(&output.stdout).unwrap()
    };
    let (k15, ds) = (kitti15.dir.to_str().unwrap(), driving.dir.to_str().unwrap());
    let both = ["--kitti", k15, "--drivingstereo", ds];
    let json = benchmark(&both);
    assert_eq!(json["protocol"], "s3");
    benchmark_column_is(&json, 0, &s3(&kitti15.frames, 3.0));
    benchmark_column_is(&json, 1, &s3(&driving.frames, 3.0));
    assert_eq!(
        json["benchmarks"][0]["unscored"],
        serde_json::json!(["000002_10", "000003_10"])
    );
    let json = benchmark(&[&both[..], &["--protocol", "pixels"]].concat());
    benchmark_column_is(&json, 0, &pixels(&kitti15.frames, 3.0));
    benchmark_column_is(&json, 1, &pixels(&driving.frames, 3.0));

    let list = dir.path().join("one.txt");
    std::fs::write(&list, "000001_10\n").unwrap();
    let bound = format!("{k15}={}", list.display());
    let json = benchmark(&["--kitti", k15, "--protocol", "kitti", "--frames", &bound]);
    assert_eq!(json["benchmarks"][0]["metric"], "d1");
    assert_eq!(json["benchmarks"][0]["images"], 1);
    benchmark_column_is(&json, 0, &kitti(&kitti15.frames[1..], 2015));

    std::fs::write(&list, "000001_10\nnowhere\n").unwrap();
    let output = run(&[
        "benchmark",
        "--kitti",
        k15,
        "--drivingstereo",
        ds,
        "--frames",
    ]
    .into_iter()
    .chain([list.to_str().unwrap()])
    .collect::<Vec<_>>());
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(
        text(&output).contains("1 listed frame(s) not found in"),
        "{}",
        text(&output)
    );
    assert!(text(&output).contains(": nowhere"), "{}", text(&output));
    assert!(
        output.stdout.is_empty(),
        "nothing is scored: {}",
        text(&output)
    );
}

/// Column `index` of `benchmark --json` holds `want`'s OCC, NOC and ALL
/// (headline) and EPE.
fn benchmark_column_is(json: &Value, index: usize, want: &Scores) {
    let column = &json["benchmarks"][index];
    assert_eq!(column["metric"], want.key.as_str(), "{json:#}");
    let close = |v: &Value, w: Option<&f64>| match (v.as_f64(), w) {
        (Some(v), Some(w)) => (v - w).abs() <= 1e-6,
        (None, None) => true,
        _ => false,
    };
    for (key, region) in [("all", "ALL"), ("noc", "NOC"), ("occ", "OCC")] {
        assert!(
            close(&column[key], want.regions.get(region)),
            "{key}: {json:#} vs {want:?}"
        );
    }
    let epe = want.epe.as_ref();
    assert!(close(&column["epe"], epe), "epe: {json:#} vs {want:?}");
}

/// `eval PREDICTIONS --kitti DIR --json` prints, under every preset, byte
/// for byte the JSON of the library's scores of the same folder (its frames without
/// ground truth included), and refuses a preset without rules for the
/// data as the library does, with its words.
#[test]
fn eval_json_is_the_librarys() {
    let dir = tempfile::tempdir().unwrap();
    let kitti = kitti_layout(dir.path(), 2015);
    let source = PairSource::Benchmark {
        benchmark: "kitti".parse().unwrap(),
        dir: kitti.dir.clone(),
    };
    for preset in PRESETS {
        let output = eval(&kitti, &kitti.predictions, preset, &[]);
        let protocol: Protocol = preset.parse().unwrap();
        let rules = match rules_for(protocol, source.dataset(), &[]) {
            Ok(rules) => rules,
            Err(refusal) => {
                assert_eq!(output.status.code(), Some(1), "{}", text(&output));
                let refusal = refusal.to_string();
                assert!(
                    text(&output).contains(&refusal),
                    "{refusal}: {}",
                    text(&output)
                );
                continue;
            }
        };
        assert!(output.status.success(), "{preset}: {}", text(&output));
        let library = score_predictions(&source, &kitti.predictions, None, &rules, &|_| {})
            .unwrap()
            .json()
            .unwrap();
        let printed = String::from_utf8_lossy(&output.stdout);
        assert_eq!(printed, format!("{library:#}\n"), "{preset}");
    }
}
