//! End-to-end tests of `mbs-tool predict`, `eval` and `benchmark` on the
//! real Middlebury Teddy pair (`testdata/`), as a single pair and laid out
//! as each benchmark's folder (KITTI 2015, Middlebury 2014, ETH3D,
//! DrivingStereo, SceneFlow).

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::{Path, PathBuf};

use common::{run, text};
use mbs_core::FloatImage;
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
    predict_writes_the_pair_and_its_colours(&out);
    let prediction = out.join("im2.pfm");
    let report = eval_with_gt_scale_scores_as_the_library(&prediction);
    eval_table_names_the_sets_and_the_pooled_line(&prediction);
    eval_of_the_pair_itself_scores_the_same(&report);
    gt_alone_says_what_it_scores();
}

/// `predict --color` of Teddy into `out` writes a disparity without holes
/// and its colour image, each at the pair's size.
fn predict_writes_the_pair_and_its_colours(out: &Path) {
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
        s(out),
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
}

/// `eval --gt --gt-scale 4` of `prediction` scores what the library test
/// measures, pooled over the one image; returns the report.
fn eval_with_gt_scale_scores_as_the_library(prediction: &Path) -> Value {
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
    report
}

/// The table `eval` prints for `prediction` names the sets and the pooled
/// line.
fn eval_table_names_the_sets_and_the_pooled_line(prediction: &Path) {
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
}

/// The pair itself, predicted by the same matcher inside eval, scores as
/// its prediction file did in `report`.
fn eval_of_the_pair_itself_scores_the_same(report: &Value) {
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
}

/// `--gt` without a prediction file or a pair says what it scores.
fn gt_alone_says_what_it_scores() {
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

/// `predict` of a benchmark folder (`flag`: `--middlebury`, `--sceneflow`,
/// ...) with the built-in matcher over 64 disparities into `out`.
fn predict_folder(flag: &str, root: &Path, out: &Path) {
    let output = run(&[
        "predict",
        flag,
        root.to_str().expect("temporary paths are UTF-8"),
        "--max-disparity",
        "64",
        "--out",
        out.to_str().expect("temporary paths are UTF-8"),
    ]);
    assert!(output.status.success(), "{}", text(&output));
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
        predict_folder(flag, root, &out);
        assert!(out.join(format!("{scene}.pfm")).is_file());
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

/// A Middlebury scene's `calib.txt` `ndisp` is the built-in matcher's
/// search range for that scene (bit-equal to `--max-disparity ndisp` on
/// the pair alone, so not the default 128), and `--max-disparity` still
/// overrides it.
#[test]
fn middlebury_calib_ndisp_is_the_search_range_unless_the_flag_says_otherwise() {
    let dir = tempfile::tempdir().unwrap();
    let middlebury = dir.path().join("MiddEval3/trainingQ");
    two_view_folder(&middlebury, "Teddy", &middlebury.join("Teddy"));
    std::fs::write(
        middlebury.join("Teddy/calib.txt"),
        "cam0=[375 0 100; 0 375 90; 0 0 1]\ndoffs=0\nbaseline=160\nwidth=450\nheight=375\nndisp=56\n",
    )
    .unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let predict = |source: &[String], max_disparity: Option<&str>, out: &Path| {
        let mut args: Vec<String> = vec!["predict".into()];
        args.extend_from_slice(source);
        if let Some(n) = max_disparity {
            args.extend(["--max-disparity".into(), n.into()]);
        }
        args.extend(["--out".into(), s(out)]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let output = run(&args);
        assert!(output.status.success(), "{}", text(&output));
    };
    let folder = [String::from("--middlebury"), s(&middlebury)];
    let pair = [
        String::from("--left"),
        s(&middlebury.join("Teddy/im0.png")),
        "--right".into(),
        s(&middlebury.join("Teddy/im1.png")),
    ];
    let map = |path: PathBuf| pfm::read_pfm_grey(&path).unwrap();
    predict(&folder, None, &dir.path().join("calib"));
    predict(&pair, Some("56"), &dir.path().join("pair56"));
    predict(&pair, None, &dir.path().join("default"));
    let calib = map(dir.path().join("calib/Teddy.pfm"));
    assert_eq!(calib, map(dir.path().join("pair56/im0.pfm")));
    assert_ne!(calib, map(dir.path().join("default/im0.pfm")));

    predict(&folder, Some("40"), &dir.path().join("flag"));
    predict(&pair, Some("40"), &dir.path().join("pair40"));
    assert_eq!(
        map(dir.path().join("flag/Teddy.pfm")),
        map(dir.path().join("pair40/im0.pfm"))
    );
}

/// The frame name of Teddy laid out as a DrivingStereo frame.
const DRIVING_STEREO_FRAME: &str = "2018-08-17-09-45-58_2018-08-17-10-23-24-800";

/// Teddy as a DrivingStereo weather folder at half size (16-bit disparity
/// PNG, value / 256, 0 where there is no ground truth), with a second
/// frame whose right view is missing.
fn driving_stereo_folder(root: &Path) {
    for folder in ["left-image-half-size", "right-image-half-size"] {
        std::fs::create_dir_all(root.join(folder)).expect("temporary folder is writable");
    }
    let frame = format!("{DRIVING_STEREO_FRAME}.png");
    std::fs::copy(
        teddy("im2.png"),
        root.join("left-image-half-size").join(&frame),
    )
    .expect("test data is readable");
    std::fs::copy(
        teddy("im6.png"),
        root.join("right-image-half-size").join(&frame),
    )
    .expect("test data is readable");
    std::fs::copy(
        teddy("im2.png"),
        root.join("left-image-half-size/broken.png"),
    )
    .expect("test data is readable");
    let gt = read_disparity(&teddy("disp2.png"), Some(4.0)).expect("test data is readable");
    for name in [frame.as_str(), "broken.png"] {
        png16::write_kitti_disparity(&root.join("disparity-map-half-size").join(name), &gt)
            .expect("temporary folder is writable");
    }
}

/// Teddy as SceneFlow's FlyingThings3D test frame `TEST/A/0000/0006`
/// (cleanpass views, PFM disparity).
fn scene_flow_folder(root: &Path) {
    let frame = root.join("frames_cleanpass/TEST/A/0000");
    for (side, file) in [("left", "im2.png"), ("right", "im6.png")] {
        std::fs::create_dir_all(frame.join(side)).expect("temporary folder is writable");
        std::fs::copy(teddy(file), frame.join(side).join("0006.png"))
            .expect("test data is readable");
    }
    let truth = root.join("disparity/TEST/A/0000/left");
    std::fs::create_dir_all(&truth).expect("temporary folder is writable");
    let gt = read_disparity(&teddy("disp2.png"), Some(4.0)).expect("test data is readable");
    pfm::write_pfm_grey(&truth.join("0006.pfm"), &gt, pfm::Endian::Little)
        .expect("temporary folder is writable");
}

/// Teddy's pooled (pixels, EPE, Out-`threshold` in percent) for the
/// prediction `file`, computed here from the ground truth's own encoding
/// (disp2.png: value / 4, 0 unknown): every pixel with ground truth
/// counts, a missing prediction is an outlier left out of the EPE.
fn teddy_scores(file: &Path, threshold: f32) -> (u64, f64, f64) {
    let gt = image::open(teddy("disp2.png"))
        .expect("test data is readable")
        .into_luma8();
    let prediction = read_disparity(file, None).expect("the prediction is readable");
    let (mut pixels, mut predicted, mut outliers, mut error_sum) = (0u64, 0u64, 0u64, 0f64);
    for (x, y, value) in gt.enumerate_pixels() {
        if value.0[0] == 0 {
            continue;
        }
        pixels += 1;
        let d = prediction.get_pixel(x, y).0[0];
        if !d.is_finite() {
            outliers += 1;
            continue;
        }
        let error = (d - f32::from(value.0[0]) / 4.0).abs();
        predicted += 1;
        error_sum += f64::from(error);
        outliers += u64::from(error > threshold);
    }
    (
        pixels,
        error_sum / predicted as f64,
        100.0 * outliers as f64 / pixels as f64,
    )
}

/// DrivingStereo's and SceneFlow's layouts in `predict` and `eval`, and
/// `benchmark` scoring Middlebury, DrivingStereo and SceneFlow folders at
/// once with each one's metric: the numbers equal a computation made here
/// from Teddy's ground truth to 1e-6 and the pixel counts exactly; OCC only
/// where the benchmark has occlusion masks; a frame that fails is counted
/// and the rest scored; a folder off its layout stops the command.
#[test]
fn benchmark_layouts_score_as_computed_independently() {
    let dir = tempfile::tempdir().unwrap();
    let driving = dir.path().join("DrivingStereo/rainy");
    driving_stereo_folder(&driving);
    let scene_flow = dir.path().join("flyingthings3d");
    scene_flow_folder(&scene_flow);
    let middlebury = dir.path().join("MiddEval3/trainingQ");
    two_view_folder(&middlebury, "Teddy", &middlebury.join("Teddy"));

    let pred = dir.path().join("pred");
    predict_folder("--sceneflow", &scene_flow, &pred);
    let predicted = pred.join("TEST/A/0000/0006.pfm");
    let scores = teddy_scores(&predicted, 3.0);
    eval_scores_sceneflow_and_drivingstereo_layouts(&pred, &scene_flow, &driving, scores);
    let per_image = dir.path().join("scores.json");
    let table =
        benchmark_scores_all_but_a_failed_frame([&middlebury, &driving, &scene_flow], &per_image);
    let (_, epe, out3) = scores;
    let (_, _, out1) = teddy_scores(&predicted, 1.0);
    benchmark_scores_each_with_its_metric(&table, epe, out3, out1);
    per_image_scores_name_the_frames(&per_image);
    benchmark_prints_the_papers_row(&scene_flow, out1);
    a_folder_off_its_layout_stops_benchmark(&middlebury, dir.path());
    predict_without_pairs_names_every_way_to_give_them(&pred);
}

/// `eval --thresholds 3` of the SceneFlow prediction in `pred` scores
/// `(pixels, epe, out3)` in SceneFlow's layout, and so does the same
/// prediction as the DrivingStereo frame's (the broken frame's ground truth
/// removed), without NOC: neither has occlusion masks.
fn eval_scores_sceneflow_and_drivingstereo_layouts(
    pred: &Path,
    scene_flow: &Path,
    driving: &Path,
    (pixels, epe, out3): (u64, f64, f64),
) {
    let predicted = pred.join("TEST/A/0000/0006.pfm");
    std::fs::copy(&predicted, pred.join(format!("{DRIVING_STEREO_FRAME}.pfm"))).unwrap();
    std::fs::remove_file(driving.join("disparity-map-half-size/broken.png")).unwrap();
    for flag in ["--sceneflow", "--drivingstereo"] {
        let root = if flag == "--sceneflow" {
            scene_flow
        } else {
            driving
        };
        let report = json_of(&run(&[
            "eval",
            pred.to_str().unwrap(),
            flag,
            root.to_str().unwrap(),
            "--thresholds",
            "3",
            "--json",
        ]));
        let all = &report["pooled"]["ALL"];
        assert_eq!(all["pixels"].as_u64(), Some(pixels), "{flag}: {report:#}");
        assert!(close(&all["epe"], epe, 1e-6), "{flag}: {report:#}");
        assert!(close(&all["out3"], out3, 1e-6), "{flag}: {report:#}");
        assert!(report["pooled"].get("NOC").is_none(), "{flag}: {report:#}");
    }
}

/// `benchmark --json --protocol pixels` (pooled over pixels) of the
/// Middlebury, DrivingStereo (its broken frame's ground truth back) and
/// SceneFlow folders, with per-image scores into
/// `per_image`: the DrivingStereo frame without a right view fails, the
/// rest is scored. Returns the table.
fn benchmark_scores_all_but_a_failed_frame(
    [middlebury, driving, scene_flow]: [&Path; 3],
    per_image: &Path,
) -> Value {
    let driving_gt = read_disparity(&teddy("disp2.png"), Some(4.0)).unwrap();
    png16::write_kitti_disparity(
        &driving.join("disparity-map-half-size/broken.png"),
        &driving_gt,
    )
    .unwrap();
    let output = run(&[
        "benchmark",
        "--middlebury",
        middlebury.to_str().unwrap(),
        "--drivingstereo",
        driving.to_str().unwrap(),
        "--sceneflow",
        scene_flow.to_str().unwrap(),
        "--max-disparity",
        "64",
        "--protocol",
        "pixels",
        "--per-image",
        per_image.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(
        text(&output).contains("1 images failed") && text(&output).contains("broken"),
        "{}",
        text(&output)
    );
    serde_json::from_slice(&output.stdout).expect("benchmark --json prints JSON")
}

/// Each of the `table`'s columns scores with its benchmark's metric:
/// Middlebury Out-2 with OCC above NOC, DrivingStereo one image (and one
/// failed) at Out-3 `out3` without OCC, SceneFlow Out-1 `out1` and EPE
/// `epe`.
fn benchmark_scores_each_with_its_metric(table: &Value, epe: f64, out3: f64, out1: f64) {
    let columns = table["benchmarks"]
        .as_array()
        .expect("a list of benchmarks");
    let column = |label: &str| {
        columns
            .iter()
            .find(|c| c["benchmark"] == label)
            .unwrap_or_else(|| panic!("no column {label}: {table:#}"))
    };
    let scores = column("Middlebury trainingQ");
    assert_eq!(scores["metric"], "out2", "{table:#}");
    assert!(scores["occ"].as_f64() > scores["noc"].as_f64(), "{table:#}");
    let scores = column("DrivingStereo rainy");
    assert_eq!(
        (scores["images"].as_u64(), scores["failed"].as_u64()),
        (Some(1), Some(1))
    );
    assert!(close(&scores["all"], out3, 1e-6), "{table:#}");
    assert!(scores["occ"].is_null(), "{table:#}");
    let scores = column("SceneFlow flyingthings3d");
    assert_eq!(scores["metric"], "out1", "{table:#}");
    assert!(close(&scores["all"], out1, 1e-6), "{table:#}");
    assert!(close(&scores["epe"], epe, 1e-6), "{table:#}");
}

/// The `--per-image` file names each benchmark's frames.
fn per_image_scores_name_the_frames(per_image: &Path) {
    let scores: Value =
        serde_json::from_str(&std::fs::read_to_string(per_image).expect("--per-image is written"))
            .expect("--per-image is JSON");
    assert_eq!(
        scores["SceneFlow flyingthings3d"]["images"][0]["name"],
        "TEST/A/0000/0006"
    );
}

/// `benchmark --protocol pixels` without `--json` prints the text table
/// and the paper's row, with SceneFlow's pooled Out-1 `out1`.
fn benchmark_prints_the_papers_row(scene_flow: &Path, out1: f64) {
    let output = run(&[
        "benchmark",
        "--sceneflow",
        scene_flow.to_str().unwrap(),
        "--max-disparity",
        "64",
        "--protocol",
        "pixels",
    ]);
    assert!(output.status.success(), "{}", text(&output));
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("SceneFlow flyingthings3d")
            && stdout.contains(&format!("| - | {out1:.2} |")),
        "{stdout}"
    );
}

/// A folder off its layout (`middlebury` as SceneFlow's) stops `benchmark`
/// before anything is scored.
fn a_folder_off_its_layout_stops_benchmark(middlebury: &Path, dir: &Path) {
    let output = run(&[
        "benchmark",
        "--sceneflow",
        middlebury.to_str().unwrap(),
        "--drivingstereo",
        dir.join("DrivingStereo/rainy").to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(
        text(&output).contains("not a SceneFlow folder") && text(&output).contains("trainingQ"),
        "{}",
        text(&output)
    );
    assert!(output.stdout.is_empty(), "{}", text(&output));
}

/// `predict` without pairs names every way to give them.
fn predict_without_pairs_names_every_way_to_give_them(pred: &Path) {
    let output = run(&["predict", "--out", pred.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(
        text(&output).contains("--drivingstereo, --sceneflow DIR"),
        "{}",
        text(&output)
    );
}

/// `submit` writes each server's layout with the prediction `predict`
/// makes of the same pair and a positive time, zips it for upload, resumes
/// without redoing a pair, and refuses a Middlebury name the server's
/// scripts could not read back.
#[test]
fn submission_folders_hold_each_servers_files() {
    let dir = tempfile::tempdir().unwrap();
    let middlebury = dir.path().join("MiddEval3/testH");
    two_view_folder(&middlebury, "Teddy", &middlebury.join("Teddy"));
    let eth3d = dir.path().join("two_view_test");
    two_view_folder(&eth3d, "teddy", &dir.path().join("two_view_test_gt/teddy"));
    let kitti = dir.path().join("testing");
    kitti_folder(&kitti);
    let pred = dir.path().join("pred");
    predict_folder("--middlebury", &middlebury, &pred);
    let predicted = read_disparity(&pred.join("Teddy.pfm"), None).unwrap();

    middlebury_submission_is_timed_zipped_and_resumed(&middlebury, dir.path(), &predicted);
    eth3d_submission_holds_the_runtime(&eth3d, dir.path(), &predicted);
    kitti_submission_holds_16_bit_disparities(&kitti, dir.path(), &predicted);
    a_middlebury_name_the_scripts_cannot_read_is_refused(&middlebury, dir.path());
}

/// `submit FLAG ROOT` with the built-in matcher over 64 disparities into
/// `out`, then `extra`.
fn submit(flag: &str, root: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut argv = vec![
        "submit",
        flag,
        root.to_str().unwrap(),
        "--max-disparity",
        "64",
        "--out",
        out.to_str().unwrap(),
    ];
    argv.extend_from_slice(extra);
    run(&argv)
}

/// The Middlebury submission (in `dir/sub-mb`) holds `predict`'s map,
/// `predicted`, and a positive time under the method's name, is zipped
/// for upload, and a second run finds the pair done.
fn middlebury_submission_is_timed_zipped_and_resumed(
    middlebury: &Path,
    dir: &Path,
    predicted: &FloatImage,
) {
    let out = dir.join("sub-mb");
    let output = submit("--middlebury", middlebury, &out, &["--name", "MBS"]);
    assert!(output.status.success(), "{}", text(&output));
    let scene = out.join("testH/Teddy");
    let written = pfm::read_pfm_grey(&scene.join("disp0MBS.pfm")).unwrap();
    assert_eq!(written.as_raw(), predicted.as_raw());
    let seconds: f64 = std::fs::read_to_string(scene.join("timeMBS.txt"))
        .unwrap()
        .trim()
        .parse()
        .expect("the time file holds seconds");
    assert!(seconds > 0.0, "{seconds}");
    assert!(
        String::from_utf8_lossy(&output.stdout).contains("middlebury_submission.zip"),
        "{}",
        text(&output)
    );
    let archive = std::fs::read(out.join("middlebury_submission.zip")).unwrap();
    assert!(
        archive
            .windows(24)
            .any(|w| w == b"testH/Teddy/disp0MBS.pfm"),
        "the archive names the scene's files"
    );
    let again = submit("--middlebury", middlebury, &out, &["--name", "MBS"]);
    assert!(
        again.status.success() && text(&again).contains("0 done, 1 skipped"),
        "{}",
        text(&again)
    );
}

/// The ETH3D submission (in `dir/sub-eth3d`) holds the runtime and
/// `predict`'s map, `predicted`, and is zipped.
fn eth3d_submission_holds_the_runtime(eth3d: &Path, dir: &Path, predicted: &FloatImage) {
    let out = dir.join("sub-eth3d");
    let output = submit("--eth3d", eth3d, &out, &[]);
    assert!(output.status.success(), "{}", text(&output));
    let runtime = std::fs::read_to_string(out.join("low_res_two_view/teddy.txt")).unwrap();
    assert!(runtime.starts_with("runtime "), "{runtime}");
    let written = pfm::read_pfm_grey(&out.join("low_res_two_view/teddy.pfm")).unwrap();
    assert_eq!(written.as_raw(), predicted.as_raw());
    assert!(out.join("eth3d_submission.zip").is_file());
}

/// The KITTI submission (in `dir/sub-kitti`) holds `predict`'s map,
/// `predicted`, as KITTI's 16-bit PNG codes, and is zipped.
fn kitti_submission_holds_16_bit_disparities(kitti: &Path, dir: &Path, predicted: &FloatImage) {
    let out = dir.join("sub-kitti");
    let output = submit("--kitti", kitti, &out, &[]);
    assert!(output.status.success(), "{}", text(&output));
    let codes = png16::read_gray16(&out.join("disp_0/000000_10.png")).unwrap();
    let expected = png16::encode_scaled(predicted, 256.0);
    assert_eq!(codes.as_raw(), expected.as_raw());
    assert!(out.join("kitti_submission.zip").is_file());
}

/// A Middlebury method name the server's scripts could not read back is
/// refused before anything is written.
fn a_middlebury_name_the_scripts_cannot_read_is_refused(middlebury: &Path, dir: &Path) {
    let output = submit(
        "--middlebury",
        middlebury,
        &dir.join("sub-bad"),
        &["--name", "my method"],
    );
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(
        text(&output).contains("letters and digits"),
        "{}",
        text(&output)
    );
    assert!(!dir.join("sub-bad").exists());
}
