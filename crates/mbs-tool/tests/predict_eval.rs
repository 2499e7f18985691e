//! End-to-end tests of `mbs-tool predict` and `mbs-tool eval` on the real
//! Middlebury Teddy pair (`testdata/`), as a single pair and laid out
//! as a KITTI 2015 training folder.

mod common;

use std::path::{Path, PathBuf};

use common::{run, text};
use mbs_core::formats::{pfm, png16, read_disparity};
use serde_json::Value;

fn teddy(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/middlebury-teddy")
        .join(file)
}

fn json_of(output: &std::process::Output) -> Value {
    assert!(output.status.success(), "{}", text(output));
    serde_json::from_slice(&output.stdout).expect("eval --json prints JSON")
}

fn close(v: &Value, expected: f64, tolerance: f64) -> bool {
    v.as_f64()
        .is_some_and(|v| (v - expected).abs() <= tolerance)
}

#[test]
fn single_pair_to_pfm_then_eval_with_gt_scale() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("pred");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let args = [
        "predict".to_string(),
        "--left".into(),
        s(&teddy("im2.png")),
        "--right".into(),
        s(&teddy("im6.png")),
        "--max-disparity".into(),
        "64".into(),
        "--out".into(),
        s(&out),
        "--color".into(),
    ];
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let output = run(&args);
    assert!(output.status.success(), "{}", text(&output));
    let disparity = pfm::read_pfm_grey(&out.join("im2.pfm")).unwrap();
    assert_eq!(disparity.dimensions(), (450, 375));
    assert!(disparity.iter().all(|d| d.is_finite()), "holes are filled");
    let color = image::open(out.join("im2_color.png")).unwrap();
    assert_eq!((color.width(), color.height()), (450, 375));

    let prediction = out.join("im2.pfm");
    let report = json_of(&run(&[
        "eval",
        prediction.to_str().unwrap(),
        "--gt",
        teddy("disp2.png").to_str().unwrap(),
        "--gt-scale",
        "4",
        "--json",
    ]));
    // The library test measures EPE 0.897 px and Out-2 7.95 % on this pair.
    let all = &report["pooled"]["ALL"];
    assert!(close(&all["epe"], 0.897, 0.002), "{report:#}");
    assert!(close(&all["out2"], 7.95, 0.01), "{report:#}");
    assert!(close(&all["density"], 100.0, 1e-9), "{report:#}");
    assert!(report["pooled"].get("NOC").is_none(), "no mask, no NOC");
    assert_eq!(report["images"].as_array().map(Vec::len), Some(1));

    // The table names the sets and the pooled line.
    let table = run(&[
        "eval",
        prediction.to_str().unwrap(),
        "--gt",
        teddy("disp2.png").to_str().unwrap(),
        "--gt-scale",
        "4",
    ]);
    let stdout = String::from_utf8_lossy(&table.stdout);
    assert!(stdout.contains("pooled") && stdout.contains("Out-2") && stdout.contains("7.95%"));

    // The pair itself, predicted by the same matcher inside eval, scores the same.
    let direct = json_of(&run(&[
        "eval",
        "--left",
        teddy("im2.png").to_str().unwrap(),
        "--right",
        teddy("im6.png").to_str().unwrap(),
        "--max-disparity",
        "64",
        "--gt",
        teddy("disp2.png").to_str().unwrap(),
        "--gt-scale",
        "4",
        "--json",
    ]));
    assert_eq!(direct["pooled"], report["pooled"], "{direct:#}");
    // --gt without a prediction file or a pair says what it scores.
    let lone = run(&["eval", "--gt", teddy("disp2.png").to_str().unwrap()]);
    assert!(!lone.status.success());
    assert!(
        text(&lone).contains("--gt scores one prediction file (PREDICTIONS) or one pair"),
        "{}",
        text(&lone)
    );
}

/// Teddy as KITTI 2015 `training`: views, disp_occ_0 and a disp_noc_0 that
/// declares the first 100 columns occluded.
fn kitti_folder(root: &Path) {
    for (folder, file) in [("image_2", "im2.png"), ("image_3", "im6.png")] {
        std::fs::create_dir_all(root.join(folder)).expect("temporary folder is writable");
        std::fs::copy(teddy(file), root.join(folder).join("000000_10.png"))
            .expect("test data is readable");
    }
    let gt = read_disparity(&teddy("disp2.png"), Some(4.0)).expect("test data is readable");
    png16::write_kitti_disparity(&root.join("disp_occ_0/000000_10.png"), &gt)
        .expect("temporary folder is writable");
    let mut noc = gt.clone();
    for (x, _, v) in noc.enumerate_pixels_mut() {
        if x < 100 {
            v.0[0] = f32::INFINITY;
        }
    }
    png16::write_kitti_disparity(&root.join("disp_noc_0/000000_10.png"), &noc)
        .expect("temporary folder is writable");
}

#[test]
fn kitti_folder_predict_resume_and_eval_by_region() {
    let dir = tempfile::tempdir().unwrap();
    let kitti = dir.path().join("training");
    kitti_folder(&kitti);
    let out = dir.path().join("pred");
    let predict = || {
        run(&[
            "predict",
            "--kitti",
            kitti.to_str().unwrap(),
            "--format",
            "png16",
            "--max-disparity",
            "64",
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let first = predict();
    assert!(
        String::from_utf8_lossy(&first.stderr).contains("1 done, 0 skipped, 0 failed"),
        "{}",
        text(&first)
    );
    assert!(out.join("000000_10.png").is_file());
    let again = predict();
    assert!(
        String::from_utf8_lossy(&again.stderr).contains("0 done, 1 skipped"),
        "{}",
        text(&again)
    );

    let report = json_of(&run(&[
        "eval",
        out.to_str().unwrap(),
        "--kitti",
        kitti.to_str().unwrap(),
        "--json",
    ]));
    let pooled = &report["pooled"];
    // KITTI PNGs round to 1/256 px, so EPE moves by at most ~0.002 px.
    assert!(close(&pooled["ALL"]["epe"], 0.897, 0.004), "{report:#}");
    assert!(close(&pooled["ALL"]["out2"], 7.95, 0.05), "{report:#}");
    let pixels = |r: &str| pooled[r]["pixels"].as_u64().unwrap_or(0);
    assert!(pixels("NOC") > 0 && pixels("OCC") > 0, "{report:#}");
    assert_eq!(pixels("NOC") + pixels("OCC"), pixels("ALL"));
    // One image: the per-image mean is the pooled value.
    assert_eq!(report["mean"]["NOC"]["epe"], pooled["NOC"]["epe"]);
    // The left border (x < 100, "occluded" here) is harder than the rest.
    assert!(pooled["OCC"]["out2"].as_f64() > pooled["NOC"]["out2"].as_f64());
}

#[test]
fn eval_names_a_missing_prediction() {
    let dir = tempfile::tempdir().unwrap();
    let kitti = dir.path().join("training");
    kitti_folder(&kitti);
    let output = run(&[
        "eval",
        dir.path().to_str().unwrap(),
        "--kitti",
        kitti.to_str().unwrap(),
    ]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("no prediction 000000_10.pfm, .png or .exr"),
        "{stderr}"
    );
}

/// Teddy as a two-camera manifest with ground truth for both directions.
fn teddy_manifest(root: &Path) -> PathBuf {
    for (file, view) in [("im2.png", "left.png"), ("im6.png", "right.png")] {
        std::fs::create_dir_all(root).expect("temporary folder is writable");
        std::fs::copy(teddy(file), root.join(view)).expect("test data is readable");
    }
    for (file, out) in [("disp2.png", "gt_0_1.pfm"), ("disp6.png", "gt_1_0.pfm")] {
        let gt = read_disparity(&teddy(file), Some(4.0)).expect("test data is readable");
        pfm::write_pfm_grey(&root.join(out), &gt, pfm::Endian::Little)
            .expect("temporary folder is writable");
    }
    let manifest = serde_json::json!({
        "format": "mbs-manifest/1",
        "name": "teddy",
        "rig": {"num_views": 2, "baseline_m": 0.1, "focal_px": 400.0, "cx": 225.0,
                "cy": 187.5, "width": 450, "height": 375},
        "samples": [{
            "id": "teddy",
            "split": "test",
            "views": ["left.png", "right.png"],
            "ground_truth": [
                {"reference": 0, "target": 1, "disparity": "gt_0_1.pfm"},
                {"reference": 1, "target": 0, "disparity": "gt_1_0.pfm"}
            ]
        }]
    });
    let path = root.join("manifest.json");
    std::fs::write(&path, manifest.to_string()).expect("temporary folder is writable");
    path
}

#[test]
fn manifest_right_view_through_mirroring() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = teddy_manifest(&dir.path().join("data"));
    let out = dir.path().join("pred_1_0");
    let output = run(&[
        "predict",
        "--manifest",
        manifest.to_str().unwrap(),
        "--pair",
        "1:0",
        "--max-disparity",
        "64",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", text(&output));
    let report = json_of(&run(&[
        "eval",
        out.to_str().unwrap(),
        "--manifest",
        manifest.to_str().unwrap(),
        "--pair",
        "1:0",
        "--json",
    ]));
    let all = &report["pooled"]["ALL"];
    println!("Teddy right view (mirrored SGM): {all}");
    // Measured: EPE 0.835 px, Out-2 6.90 % on the right view's GT.
    assert!(close(&all["out2"], 6.90, 0.05), "{report:#}");
    assert!(close(&all["epe"], 0.835, 0.005), "{report:#}");
    // Scored against the wrong direction's GT it is far off.
    let wrong = json_of(&run(&[
        "eval",
        out.to_str().unwrap(),
        "--manifest",
        manifest.to_str().unwrap(),
        "--pair",
        "0:1",
        "--json",
    ]));
    assert!(
        wrong["pooled"]["ALL"]["out2"].as_f64() > Some(20.0),
        "{wrong:#}"
    );
}

/// Teddy as a Middlebury 2014 scene (`root/Teddy/`) or an ETH3D one (the
/// views in `root/teddy/`, the ground truth in `<root>_gt/teddy/`): im0/im1,
/// disp0GT.pfm with `inf` where there is no ground truth, and a
/// mask0nocc.png that says 128 (occluded) in the first 100 columns, 0 where
/// there is no ground truth and 255 elsewhere.
fn two_view_folder(root: &Path, scene: &str, truth: &Path) {
    std::fs::create_dir_all(root.join(scene)).expect("temporary folder is writable");
    std::fs::create_dir_all(truth).expect("temporary folder is writable");
    std::fs::copy(teddy("im2.png"), root.join(scene).join("im0.png"))
        .expect("test data is readable");
    std::fs::copy(teddy("im6.png"), root.join(scene).join("im1.png"))
        .expect("test data is readable");
    let gt = read_disparity(&teddy("disp2.png"), Some(4.0)).expect("test data is readable");
    pfm::write_pfm_grey(&truth.join("disp0GT.pfm"), &gt, pfm::Endian::Little)
        .expect("temporary folder is writable");
    let mask = mbs_core::MaskImage::from_fn(gt.width(), gt.height(), |x, y| {
        let level = match (gt.get_pixel(x, y).0[0].is_finite(), x < 100) {
            (false, _) => 0,
            (true, true) => 128,
            (true, false) => 255,
        };
        image::Luma([level])
    });
    mbs_core::formats::rgb::write_mask_png(&truth.join("mask0nocc.png"), &mask)
        .expect("temporary folder is writable");
}

/// `predict` and `eval` on Middlebury's and ETH3D's own layouts: the scenes
/// are the pairs, named after their folders, and scored by region with
/// the masks' 255 as non-occluded, as the same pair in a KITTI folder is
/// (there to 1/256 px).
#[test]
fn middlebury_and_eth3d_folders_predict_and_eval_by_region() {
    let dir = tempfile::tempdir().unwrap();
    let middlebury = dir.path().join("MiddEval3/trainingQ");
    two_view_folder(&middlebury, "Teddy", &middlebury.join("Teddy"));
    let eth3d = dir.path().join("two_view_training");
    two_view_folder(
        &eth3d,
        "teddy",
        &dir.path().join("two_view_training_gt/teddy"),
    );
    for (flag, root, scene) in [
        ("--middlebury", &middlebury, "Teddy"),
        ("--eth3d", &eth3d, "teddy"),
    ] {
        let out = dir.path().join(format!("pred{flag}"));
        let output = run(&[
            "predict",
            flag,
            root.to_str().unwrap(),
            "--max-disparity",
            "64",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(output.status.success(), "{}", text(&output));
        assert!(
            out.join(format!("{scene}.pfm")).is_file(),
            "{}",
            text(&output)
        );
        let report = json_of(&run(&[
            "eval",
            out.to_str().unwrap(),
            flag,
            root.to_str().unwrap(),
            "--json",
        ]));
        let pooled = &report["pooled"];
        assert!(
            close(&pooled["ALL"]["epe"], 0.897, 0.004),
            "{flag}: {report:#}"
        );
        let pixels = |r: &str| pooled[r]["pixels"].as_u64().unwrap_or(0);
        assert!(pixels("NOC") > 0 && pixels("OCC") > 0, "{flag}: {report:#}");
        assert_eq!(pixels("NOC") + pixels("OCC"), pixels("ALL"));
        assert!(pooled["OCC"]["out2"].as_f64() > pooled["NOC"]["out2"].as_f64());
    }
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let output = run(&["eval", "--middlebury", empty.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(
        text(&output).contains("no Middlebury scene"),
        "{}",
        text(&output)
    );
}
