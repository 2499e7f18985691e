//! `export --format onnx`: trained networks leave mbs as ONNX models that
//! `predict --model --card` runs to the same disparities as `predict
//! --checkpoint`, on real Middlebury frames, through the real ONNX Runtime;
//! bad requests are refused before anything is written.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use mbs_core::formats::pfm::read_pfm_grey;

mod common;
use common::{refused, run, synth, text};

const TEDDY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../testdata/middlebury-teddy"
);

/// Trains `backbone` (small) for 2 steps into `dir/run-NAME`.
fn trained(dir: &Path, manifest: &str, backbone: &str, settings: &[&str]) -> PathBuf {
    let out = dir.join(format!("run-{backbone}"));
    let mut args = vec![
        "train",
        manifest,
        "--out",
        out.to_str().unwrap(),
        "--backbone",
        backbone,
        "--steps",
        "2",
        "--batch-size",
        "1",
        "--crop",
        "64x128",
        "--max-disparity",
        "32",
        "--val-every",
        "2",
        "--set",
        "data.val_samples=1",
    ];
    for setting in settings {
        args.extend(["--set", setting]);
    }
    let output = run(&args);
    assert!(output.status.success(), "{}", text(&output));
    out
}

/// `predict` on Teddy with `source`, its disparity map.
fn predict(dir: &Path, name: &str, source: &[&str]) -> Vec<f32> {
    let out = dir.join(name);
    let (left, right) = (format!("{TEDDY}/im2.png"), format!("{TEDDY}/im6.png"));
    let mut args = vec![
        "predict",
        "--left",
        &left,
        "--right",
        &right,
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(source);
    let output = run(&args);
    assert!(output.status.success(), "{}", text(&output));
    read_pfm_grey(&out.join("im2.pfm")).unwrap().into_raw()
}

/// `predict --model MODEL --card CARD` on Teddy, its disparity map.
fn predict_model(dir: &Path, name: &str, model: &Path, card: &Path) -> Vec<f32> {
    let (model, card) = (model.to_str().unwrap(), card.to_str().unwrap());
    predict(
        dir,
        &format!("{name}-onnx"),
        &["--model", model, "--card", card],
    )
}

/// Exports `run` at Teddy's size and checks `predict --model --card`
/// against `predict --checkpoint` on Teddy.
fn exported_agrees(dir: &Path, run_dir: &Path, name: &str) {
    let model = dir.join(format!("{name}.onnx"));
    let output = run(&[
        "export",
        run_dir.to_str().unwrap(),
        "--out",
        model.to_str().unwrap(),
        "--size",
        "375x450",
    ]);
    assert!(output.status.success(), "{}", text(&output));
    assert!(
        text(&output).contains("agrees with mbs"),
        "{}",
        text(&output)
    );
    let card = dir.join(format!("{name}.card.json"));
    let report = std::fs::read_to_string(dir.join(format!("{name}.report.md"))).unwrap();
    assert!(report.contains("static shapes: yes"), "{report}");
    assert!(report.contains("GridSample: 0"), "{report}");
    let onnx = predict_model(dir, name, &model, &card);
    let ours = predict(
        dir,
        &format!("{name}-mbs"),
        &["--checkpoint", run_dir.to_str().unwrap()],
    );
    let differences: Vec<f32> = ours.iter().zip(&onnx).map(|(a, b)| (a - b).abs()).collect();
    let largest = differences.iter().copied().fold(0.0, f32::max);
    let mean = differences.iter().sum::<f32>() / differences.len() as f32;
    println!(
        "{name}: predict --model against --checkpoint on Teddy: largest {largest:e}, mean {mean:e} px"
    );
    assert!(
        largest <= 1e-2 && mean <= 1e-3,
        "{name}: largest {largest}, mean {mean}"
    );
}

#[test]
fn trained_networks_run_through_onnx_runtime_as_through_mbs() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = synth(&dir.path().join("data"));
    let raft = [
        "network.raft_stereo.hidden_dim=32",
        "network.raft_stereo.train_iters=2",
        "network.raft_stereo.test_iters=3",
    ];
    let igev = [
        "network.igev.hidden_dim=32",
        "network.igev.train_iters=2",
        "network.igev.test_iters=3",
        "network.igev.max_disp=64",
    ];
    for (backbone, settings) in [
        ("compact", &[][..]),
        ("raft-stereo", &raft[..]),
        ("igev", &igev[..]),
    ] {
        let run_dir = trained(dir.path(), &manifest, backbone, settings);
        exported_agrees(dir.path(), &run_dir, backbone);
        if backbone != "compact" {
            weights_export_agrees(dir.path(), &run_dir, backbone, settings);
        }
    }
}

/// Official-key weights (the run's teacher as `export` writes it for the
/// official code) exported with `--weights` and `--iters 2` agree with
/// `predict --weights` at 2 iterations.
fn weights_export_agrees(dir: &Path, run_dir: &Path, backbone: &str, settings: &[&str]) {
    let weights = dir.join(format!("{backbone}.safetensors"));
    let output = run(&[
        "export",
        run_dir.to_str().unwrap(),
        "--out",
        weights.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", text(&output));
    let name = format!("{backbone}-weights");
    let model = dir.join(format!("{name}.onnx"));
    let weights_s = weights.to_str().unwrap();
    let mut args = vec!["export", "--backbone", backbone, "--weights", weights_s];
    args.extend([
        "--out",
        model.to_str().unwrap(),
        "--size",
        "375x450",
        "--iters",
        "2",
    ]);
    let output = run(&[args, set_args(settings)].concat());
    assert!(output.status.success(), "{}", text(&output));
    let card = dir.join(format!("{name}.card.json"));
    let onnx = predict_model(dir, &name, &model, &card);
    let iterations = format!("network.{}.test_iters=2", backbone.replace('-', "_"));
    let mut source = vec!["--backbone", backbone, "--weights", weights_s];
    source.extend(set_args(settings));
    source.extend(["--set", &iterations]);
    let ours = predict(dir, &format!("{name}-mbs"), &source);
    let largest = ours
        .iter()
        .zip(&onnx)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    println!("{name}: predict --model against --weights on Teddy: largest {largest:e} px");
    assert!(largest <= 1e-2, "{name}: largest {largest}");
}

/// `--set S` for each setting.
fn set_args<'a>(settings: &[&'a str]) -> Vec<&'a str> {
    settings.iter().flat_map(|s| ["--set", *s]).collect()
}

/// Refused `export` requests and words their errors must say.
fn bad_cases<'a>(
    run_s: &'a str,
    out_s: &'a str,
    left: &'a str,
    right: &'a str,
) -> Vec<(Vec<&'a str>, &'static [&'static str])> {
    vec![
        (vec!["export", run_s, "--out", out_s], &["--size"]),
        (
            vec!["export", run_s, "--out", out_s, "--size", "8x5000"],
            &["32x4096", "nearest"],
        ),
        (
            vec![
                "export", run_s, "--out", out_s, "--size", "64x64", "--iters", "4",
            ],
            &["compact", "iterations"],
        ),
        (
            vec![
                "export",
                run_s,
                "--out",
                out_s,
                "--size",
                "64x64",
                "--tolerance",
                "0,0",
            ],
            &["disagrees", "tolerance"],
        ),
        (
            vec![
                "export",
                run_s,
                "--out",
                left,
                "--format",
                "onnx",
                "--size",
                "64x64",
                "--check-pair",
                left,
                right,
            ],
            &["overwrite", "reads"],
        ),
    ]
}

#[test]
fn bad_requests_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = synth(&dir.path().join("data"));
    let run_dir = trained(dir.path(), &manifest, "compact", &[]);
    let run_s = run_dir.to_str().unwrap();
    let out = dir.path().join("net.onnx");
    let out_s = out.to_str().unwrap();
    let left = dir.path().join("im2.png");
    std::fs::copy(format!("{TEDDY}/im2.png"), &left).unwrap();
    let left = left.to_str().unwrap().to_string();
    let right = format!("{TEDDY}/im6.png");
    let cases = bad_cases(run_s, out_s, &left, &right);
    for (args, words) in cases {
        refused(&run(&args), words);
        assert!(
            !out.exists() && !dir.path().join("net.card.json").exists(),
            "{args:?} wrote"
        );
    }
    assert!(!dir.path().join("im2.card.json").exists());
    // A card of the user's under the name beside --out, with no model there.
    let card = dir.path().join("net.card.json");
    std::fs::write(&card, "{\"name\": \"mine\"}").unwrap();
    let output = run(&["export", run_s, "--out", out_s, "--size", "64x64"]);
    refused(&output, &["net.card.json", "would be replaced"]);
    assert_eq!(
        std::fs::read_to_string(&card).unwrap(),
        "{\"name\": \"mine\"}"
    );
    assert!(!out.exists());
    let teddy = std::fs::read(format!("{TEDDY}/im2.png")).unwrap();
    assert_eq!(
        std::fs::read(&left).unwrap(),
        teddy,
        "the check pair changed"
    );
}
