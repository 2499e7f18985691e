//! `predict` and `eval` on synthetic scenes, whose exact ground truth and
//! occlusion masks come from the renderer: the built-in matcher must get
//! Out-3 over non-occluded pixels below 5 %.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::Path;

use common::{run, text};

#[test]
fn built_in_matcher_on_synthetic_scenes_scores_below_5_percent_out3_noc() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    synthesise_three_view_scenes(&data);
    let manifest = data.join("manifest.json");
    let pred = dir.path().join("pred");
    // Pair 0:2 is two baselines; its ground truth is 2x the one-step file.
    let output = run(&[
        "predict",
        "--manifest",
        &s(&manifest),
        "--pair",
        "0:2",
        "--max-disparity",
        "96",
        "--out",
        &s(&pred),
    ]);
    assert!(output.status.success(), "{}", text(&output));
    let output = run(&[
        "eval",
        &s(&pred),
        "--manifest",
        &s(&manifest),
        "--pair",
        "0:2",
        "--json",
    ]);
    assert!(output.status.success(), "{}", text(&output));
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let pooled = &report["pooled"];
    println!("synthetic 0:2 pooled: {pooled:#}");
    let out3_noc = pooled["NOC"]["out3"].as_f64().unwrap();
    let epe_noc = pooled["NOC"]["epe"].as_f64().unwrap();
    assert!(out3_noc < 5.0, "Out-3 NOC {out3_noc} %");
    assert!(epe_noc < 1.5, "EPE NOC {epe_noc}");
    let out3_all = pooled["ALL"]["out3"].as_f64().unwrap();
    assert!(
        out3_all >= out3_noc,
        "occluded pixels are harder: ALL {out3_all} vs NOC {out3_noc}"
    );
}

/// `synth` of two 320x192 frames of three views in Town01 under two
/// weathers into `data`.
fn synthesise_three_view_scenes(data: &Path) {
    let output = run(&[
        "synth",
        "--out",
        data.to_str().unwrap(),
        "--views",
        "3",
        "--towns",
        "Town01",
        "--weathers",
        "ClearNoon,CloudyNoon",
        "--frames",
        "2",
        "--width",
        "320",
        "--height",
        "192",
        "--focal",
        "160",
    ]);
    assert!(output.status.success(), "{}", text(&output));
}
