//! The README's main job, `mbs-tool demo`, run whole (issue 53): every
//! figure the README promises is checked within a stated tolerance, so a
//! change that breaks the main job or its promises fails CI. The test
//! profile gives the release build's figures (same seeds, same arithmetic):
//! 0.0010 px, 30.78 and 32.78 dB, Out-3 67.18 % falling to 3.97 %, EPE 8.12
//! to 0.76 px when this test was written.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::Path;

use common::{lines, mbs_tool, text};
use serde_json::Value;

/// The number after `key` on each line of `log` that holds `line_holds`,
/// e.g. 0.0010 from `... EPE 0.0010 px` for `key` "EPE".
fn figures_after(log: &str, line_holds: &str, key: &str) -> Vec<f64> {
    log.lines()
        .filter(|line| line.contains(line_holds))
        .filter_map(|line| {
            let rest = &line[line.find(key)? + key.len()..];
            rest.split_whitespace().next()?.parse().ok()
        })
        .collect()
}

/// `value` lies in `low..=high`, or the test fails naming `what`.
fn within(what: &str, value: f64, (low, high): (f64, f64)) {
    assert!(
        (low..=high).contains(&value),
        "{what}: {value} is outside the README's promise [{low}, {high}]"
    );
}

/// The teacher's validation scores over all pixels at the run's first and
/// last validation: (EPE, Out-3) each.
fn first_and_last_validation(run: &Path) -> [(f64, f64); 2] {
    let log = lines(&run.join("val.jsonl"));
    let scores = |entry: &Value| {
        let all = &entry["ALL"];
        (all["epe"].as_f64().unwrap(), all["out3"].as_f64().unwrap())
    };
    assert_eq!(log.first().unwrap()["step"], 0, "{log:?}");
    assert_eq!(log.last().unwrap()["step"], 300, "{log:?}");
    [scores(&log[0]), scores(log.last().unwrap())]
}

#[test]
fn the_demo_keeps_the_readmes_promises() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mbs-demo");
    let output = mbs_tool()
        .arg("demo")
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", text(&output));
    let log = String::from_utf8_lossy(&output.stderr);
    // "checks the decoded disparity against the renderer's exact ground
    // truth (EPE 0.001 px)": KITTI PNG quantisation is 1/256 px.
    let decoded = figures_after(&log, "nearer than 200 m", "EPE");
    assert_eq!(decoded.len(), 1, "{log}");
    within("decoded disparity EPE (px)", decoded[0], (0.0, 0.002));
    // "compares them with the rendered views (about 31-33 dB PSNR)".
    let views = figures_after(&log, "vs rendered camera", "PSNR");
    assert_eq!(views.len(), 2, "{log}");
    for psnr in views {
        within("extrapolated view PSNR (dB)", psnr, (30.0, 34.0));
    }
    // "Out-3 over all pixels falls from 67 % (untrained) to 4.0 %, EPE from
    // 8.1 to 0.76 px".
    let [(epe_before, out3_before), (epe_after, out3_after)] =
        first_and_last_validation(&out.join("run"));
    within("untrained Out-3 ALL (%)", out3_before, (60.0, 75.0));
    within("untrained EPE (px)", epe_before, (7.0, 9.5));
    within("trained Out-3 ALL (%)", out3_after, (3.0, 5.0));
    within("trained EPE (px)", epe_after, (0.65, 0.9));
    for picture in ["preview.png", "loss.png", "val.png"] {
        let found = [out.join("extrapolated"), out.join("run")]
            .iter()
            .any(|folder| folder.join(picture).is_file());
        assert!(found, "{picture} is missing");
    }
}
