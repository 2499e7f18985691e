//! `mbs-tool predict --model … --card …` and `mbs-tool extrapolate
//! --model … --card … --inpaint onnx:…` on the test models of
//! `testdata/onnx/` with real ONNX Runtime (from tools/setup-ort.sh).

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::{Path, PathBuf};

use common::{run, text};
use image::Rgb;
use mbs_core::RgbImage;
use mbs_core::formats::rgb::{read_mask, read_rgb};
use mbs_core::formats::{pfm, rgb};

fn fixture(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/onnx")
        .join(name)
        .display()
        .to_string()
}

fn pair(dir: &std::path::Path) -> (String, String) {
    let left = dir.join("left.png");
    let right = dir.join("right.png");
    rgb::write_rgb_png(&left, &RgbImage::from_pixel(37, 21, Rgb([100; 3])))
        .expect("write left view");
    rgb::write_rgb_png(&right, &RgbImage::from_pixel(37, 21, Rgb([40; 3])))
        .expect("write right view");
    (left.display().to_string(), right.display().to_string())
}

#[test]
fn predict_runs_an_onnx_model_with_a_card_file() {
    let dir = tempfile::tempdir().unwrap();
    let (left, right) = pair(dir.path());
    let out = dir.path().join("pred");
    let model = fixture("stereo_negative.onnx");
    let card = fixture("stereo_negative.json");
    let args = [
        "predict", "--left", &left, "--right", &right, "--model", &model, "--card", &card,
    ];
    let output = run(&[&args[..], &["--out", out.to_str().unwrap(), "--color"]].concat());
    assert!(output.status.success(), "{}", text(&output));
    let disparity = pfm::read_pfm_grey(&out.join("left.pfm")).unwrap();
    assert_eq!(disparity.dimensions(), (37, 21));
    // 0.5 * 100 + 0.25 * 40 + 1 = 61, read through the card's sign -1; the
    // last column's right neighbour is padding (replicated): also 61.
    assert!(
        disparity.iter().all(|&d| (d - 61.0).abs() < 1e-3),
        "{:?}",
        &disparity.as_raw()[..4]
    );
    assert!(out.join("left_color.png").is_file());
}

#[test]
fn predict_explains_onnx_setup_problems() {
    let dir = tempfile::tempdir().unwrap();
    let (left, right) = pair(dir.path());
    let out = dir.path().join("pred").display().to_string();
    let model = fixture("stereo_dynamic.onnx");
    let base = [
        "predict", "--left", &left, "--right", &right, "--out", &out, "--model", &model,
    ];
    cards_that_do_not_fit_are_named(&base);
    ort_libraries_that_do_not_load_are_named(dir.path(), &base);
    let card = fixture("stereo_dynamic.json");
    devices_that_cannot_run_are_named(&base, &card);
    an_allowed_cpu_fallback_runs_and_says_so(&base, &card);
}

/// The command `base` with `extra` fails, saying `message`.
fn fails_with(base: &[&str], extra: &[&str], message: &str) {
    let output = run(&[base, extra].concat());
    assert!(!output.status.success(), "{}", text(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains(message),
        "expected {message:?} in\n{}",
        text(&output)
    );
}

/// A card of no known name, and one whose output is not the model's, are
/// named (`base`: the command without a card).
fn cards_that_do_not_fit_are_named(base: &[&str]) {
    fails_with(
        base,
        &["--card", "no-such-card"],
        "no built-in card of that name",
    );
    fails_with(
        base,
        &["--card", "crestereo"],
        "the card's output \"output\" is not an output of the model",
    );
}

/// An `--ort-lib` that is not there, or is no library (a file written in
/// `dir`: the loader's reason, with the path), is named.
fn ort_libraries_that_do_not_load_are_named(dir: &Path, base: &[&str]) {
    fails_with(
        base,
        &["--card", "igev", "--ort-lib", "/no/libonnxruntime.so"],
        "--ort-lib = /no/libonnxruntime.so: no such file",
    );
    let fake = dir.join("libonnxruntime.so.1.31.1");
    std::fs::write(&fake, b"not a library").expect("write the fake library");
    let fake = fake.display().to_string();
    fails_with(
        base,
        &["--card", "igev", "--ort-lib", &fake],
        &format!("{fake}: cannot load ONNX Runtime"),
    );
}

/// CUDA in a build without it, and a device of no known kind, are named
/// (the model with its `card`).
fn devices_that_cannot_run_are_named(base: &[&str], card: &str) {
    #[cfg(not(feature = "cuda"))]
    fails_with(
        base,
        &["--card", card, "--device", "cuda"],
        "device cuda:0: this build of mbs has no CUDA support",
    );
    fails_with(
        base,
        &["--card", card, "--device", "gpu"],
        "device `gpu`: unknown device",
    );
}

/// With the fallback allowed, a run on a CUDA device it cannot have goes
/// on on the CPU and says so.
fn an_allowed_cpu_fallback_runs_and_says_so(base: &[&str], card: &str) {
    let output = run(&[
        base,
        &["--card", card, "--device", "cuda:1", "--allow-cpu-fallback"],
    ]
    .concat());
    assert!(output.status.success(), "{}", text(&output));
    #[cfg(not(feature = "cuda"))]
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("running on cpu"),
        "{}",
        text(&output)
    );
}

#[test]
fn extrapolate_uses_onnx_stereo_and_inpainting_models() {
    let dir = tempfile::tempdir().unwrap();
    let (left, right) = (dir.path().join("l.png"), dir.path().join("r.png"));
    rgb::write_rgb_png(&left, &dark_texture(0)).unwrap();
    rgb::write_rgb_png(&right, &dark_texture(5)).unwrap();
    let out = dir.path().join("out");
    let stereo = fixture("stereo_dynamic.onnx");
    let inpaint = format!("onnx:{}", fixture("inpaint_migan.onnx"));
    let (stereo_card, inpaint_card) = (
        fixture("stereo_dynamic.json"),
        fixture("inpaint_migan.json"),
    );
    let output = run(&[
        "extrapolate",
        "--left",
        left.to_str().unwrap(),
        "--right",
        right.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--model",
        &stereo,
        "--card",
        &stereo_card,
        "--inpaint",
        &inpaint,
        "--inpaint-card",
        &inpaint_card,
    ]);
    assert!(output.status.success(), "{}", text(&output));
    the_left_disparity_is_the_stereo_models(&out);
    holes_are_filled_by_the_inpainting_model(&out);
}

/// A dark texture, different per `seed`: the test stereo model gives
/// disparities of 1 to 20 px on these.
fn dark_texture(seed: u32) -> RgbImage {
    RgbImage::from_fn(64, 40, |x, y| {
        Rgb([
            ((x * 5 + y * 3 + seed) % 24) as u8,
            ((x + y * 7) % 20) as u8,
            8,
        ])
    })
}

/// The left view's disparity in `out` is the model's function (0.5 mean
/// left + 0.25 mean right one column on + 1).
fn the_left_disparity_is_the_stereo_models(out: &Path) {
    let d2 = pfm::read_pfm_grey(&out.join("disparity_2.pfm")).unwrap();
    let mean = |im: &RgbImage, x: u32, y: u32| {
        im.get_pixel(x, y)
            .0
            .iter()
            .map(|&v| f32::from(v))
            .sum::<f32>()
            / 3.0
    };
    let (l, r) = (dark_texture(0), dark_texture(5));
    let expected = 0.5 * mean(&l, 10, 7) + 0.25 * mean(&r, 11, 7) + 1.0;
    assert!((d2.get_pixel(10, 7).0[0] - expected).abs() < 1e-3);
}

/// Synthesised pixels in `out` come from the MI-GAN-style model: 77
/// everywhere.
fn holes_are_filled_by_the_inpainting_model(out: &Path) {
    let (image_1, mask_1) = (
        read_rgb(&out.join("image_1.png")).unwrap(),
        read_mask(&out.join("mask_1.png")).unwrap(),
    );
    let holes: Vec<_> = mask_1
        .enumerate_pixels()
        .filter(|(_, _, m)| m.0[0] == 255)
        .collect();
    assert!(!holes.is_empty());
    for (x, y, _) in holes {
        assert_eq!(*image_1.get_pixel(x, y), Rgb([77; 3]), "({x}, {y})");
    }
}

#[test]
fn extrapolate_names_missing_onnx_cards() {
    let dir = tempfile::tempdir().unwrap();
    let (left, right) = pair(dir.path());
    let out = dir.path().join("out").display().to_string();
    let stereo = fixture("stereo_dynamic.onnx");
    let output = run(&[
        "extrapolate",
        "--left",
        &left,
        "--right",
        &right,
        "--out",
        &out,
        "--model",
        &stereo,
    ]);
    assert!(!output.status.success());
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("--card <NAME|FILE.json>"),
        "{}",
        text(&output)
    );
    let output = run(&[
        "extrapolate",
        "--left",
        &left,
        "--right",
        &right,
        "--out",
        &out,
        "--inpaint",
        "onnx:",
    ]);
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("invalid inpainter"),
        "{}",
        text(&output)
    );
}
