//! End-to-end tests of `mbs-tool validate` on a synthetic dataset with each
//! kind of corruption a real dataset suffers.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::Path;

use common::{run, text};
use mbs_core::formats::{png16, rgb};
use serde_json::Value;

fn synth(out: &Path, frames: &str) {
    let output = run(&[
        "synth",
        "--out",
        out.to_str().unwrap(),
        "--towns",
        "Town01,Town10",
        "--weathers",
        "ClearNoon",
        "--frames",
        frames,
        "--width",
        "64",
        "--height",
        "48",
        "--focal",
        "40",
        "--supersample",
        "1",
    ]);
    assert!(output.status.success(), "{}", text(&output));
}

fn validate_json(manifest: &Path, deep: bool) -> (bool, Value) {
    let mut args = vec!["validate", manifest.to_str().unwrap(), "--json"];
    if deep {
        args.push("--deep");
    }
    let output = run(&args);
    let report: Value =
        serde_json::from_slice(&output.stdout).unwrap_or_else(|_| panic!("{}", text(&output)));
    (output.status.success(), report)
}

#[test]
fn clean_synthetic_dataset_passes_fast_and_deep() {
    let dir = tempfile::tempdir().unwrap();
    synth(dir.path(), "2");
    let manifest = dir.path().join("manifest.json");
    for deep in [false, true] {
        let (ok, report) = validate_json(&manifest, deep);
        assert!(ok, "{report:#}");
        assert_eq!(report["samples"], 4);
        assert_eq!(report["problems"].as_array().unwrap().len(), 0);
        // 5 views + depth + 5 disparities + 20 occlusion masks per sample.
        assert_eq!(report["files_checked"], 4 * 31);
    }
    let output = run(&["validate", manifest.to_str().unwrap()]);
    assert!(output.status.success(), "{}", text(&output));
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("0 problem(s)"),
        "{}",
        text(&output)
    );
}

#[test]
fn every_kind_of_corruption_is_reported_for_its_sample() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    synth(root, "5");
    let manifest_path = root.join("manifest.json");
    let ids = corrupt_one_sample_per_kind(root, &manifest_path);
    for deep in [false, true] {
        each_corruption_is_reported_for_its_sample(&manifest_path, &ids, deep);
    }
    the_line_report_names_the_sample_and_the_file(&manifest_path, &ids);
}

/// What [`corrupt_one_sample_per_kind`] does to each sample (by index):
/// the kind of problem `validate` reports for it and how the reported path
/// ends. Sample 5 shares sample 4's id; sample 9 is untouched.
const CORRUPTIONS: [(usize, &str, &str); 8] = [
    (0, "missing_file", "rgb_3.png"),
    (1, "truncated", "rgb_1.png"),
    (2, "wrong_size", "rgb_2.png"),
    (3, "wrong_pixel_type", "depth_0.png"),
    (4, "duplicate_id", ""),
    (6, "schema", "/samples/6/split"),
    (7, "view_count", ""),
    (8, "checksum_mismatch", "rgb_0.png"),
];

/// Corrupts the ten samples of the set in `root` (manifest at
/// `manifest_path`) one kind each, as [`CORRUPTIONS`] lists; returns the
/// samples' ids.
fn corrupt_one_sample_per_kind(root: &Path, manifest_path: &Path) -> Vec<String> {
    let mut manifest: Value =
        serde_json::from_str(&std::fs::read_to_string(manifest_path).unwrap()).unwrap();
    let ids: Vec<String> = manifest["samples"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["id"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(ids.len(), 10);
    let file = |i: usize, name: &str| root.join(&ids[i]).join(name);

    // 0: missing file.
    std::fs::remove_file(file(0, "rgb_3.png")).unwrap();
    // 1: truncated PNG.
    let bytes = std::fs::read(file(1, "rgb_1.png")).unwrap();
    std::fs::write(file(1, "rgb_1.png"), &bytes[..bytes.len() - 40]).unwrap();
    // 2: wrong image size.
    rgb::write_rgb_png(&file(2, "rgb_2.png"), &image::RgbImage::new(32, 48)).unwrap();
    // 3: 16-bit depth PNG of the right size.
    png16::write_depth_mm(&file(3, "depth_0.png"), &mbs_core::FloatImage::new(64, 48)).unwrap();
    // 4 and 5: duplicate id.
    manifest["samples"][5]["id"] = Value::String(ids[4].clone());
    // 6: invalid schema field.
    manifest["samples"][6]["split"] = Value::String("training".into());
    // 7: wrong number of views.
    manifest["samples"][7]["views"]
        .as_array_mut()
        .unwrap()
        .pop();
    // 8: checksum mismatch: a valid image of the right size with other pixels.
    let view = file(8, "rgb_0.png");
    let mut img = rgb::read_rgb(&view).unwrap();
    img.get_pixel_mut(3, 3).0[0] ^= 0xff;
    rgb::write_rgb_png(&view, &img).unwrap();
    std::fs::write(
        manifest_path,
        serde_json::to_string_pretty(&manifest).unwrap(),
    )
    .unwrap();
    ids
}

/// `validate --json` (`--deep` if `deep`) of the corrupt set fails and
/// reports each of [`CORRUPTIONS`] for its sample, and nothing for the
/// untouched sample 9.
fn each_corruption_is_reported_for_its_sample(manifest_path: &Path, ids: &[String], deep: bool) {
    let (ok, report) = validate_json(manifest_path, deep);
    assert!(!ok, "a corrupt dataset must fail");
    let problems = report["problems"].as_array().unwrap();
    let found = |sample: &str, kind: &str, path_end: &str| {
        problems.iter().any(|p| {
            p["sample"] == sample
                && p["kind"] == kind
                && p["path"].as_str().unwrap_or("").ends_with(path_end)
        })
    };
    for (i, kind, path) in CORRUPTIONS {
        assert!(
            found(&ids[i], kind, path),
            "deep={deep}: no {kind} for {} in {problems:#?}",
            ids[i]
        );
    }
    assert!(
        !problems.iter().any(|p| p["sample"] == ids[9].as_str()),
        "{problems:#?}"
    );
}

/// The line report names the sample and the file, and the exit code is
/// non-zero.
fn the_line_report_names_the_sample_and_the_file(manifest_path: &Path, ids: &[String]) {
    let output = run(&["validate", manifest_path.to_str().unwrap()]);
    assert!(!output.status.success());
    let stdout = String::from_utf8_lossy(&output.stdout);
    let expected = format!("sample {}: {}/rgb_3.png: missing file", ids[0], ids[0]);
    assert!(stdout.contains(&expected), "{}", text(&output));
}

#[test]
fn unreadable_manifest_is_one_clear_problem() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("manifest.json");
    std::fs::write(&path, "{ not json").unwrap();
    let output = run(&["validate", path.to_str().unwrap()]);
    assert!(!output.status.success());
    assert!(
        String::from_utf8_lossy(&output.stdout).contains("not valid JSON"),
        "{}",
        text(&output)
    );
    let output = run(&["validate", dir.path().join("none.json").to_str().unwrap()]);
    assert!(!output.status.success());
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("none.json"),
        "{}",
        text(&output)
    );
}
