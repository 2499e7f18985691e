//! End-to-end tests of `mbs-tool extrapolate`: the synthetic oracle (exact
//! disparity, rendered outer views), the built-in matcher on real Tsukuba
//! views, and a KITTI batch with broken frames, a manifest and previews.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::{Path, PathBuf};

use common::{run, text};
use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_core::formats::rgb::{read_mask, read_rgb, write_rgb_png};
use mbs_core::{FloatImage, MaskImage};
use mbs_image::quality::psnr;

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn tsukuba(col: u32) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!(
        "../../testdata/middlebury-tsukuba-row3/scene1.row3.col{col}.ppm"
    ))
}

fn inverted(mask: &MaskImage) -> MaskImage {
    MaskImage::from_fn(mask.width(), mask.height(), |x, y| {
        image::Luma([255 - mask.get_pixel(x, y).0[0]])
    })
}

#[test]
fn synthetic_oracle_reproduces_the_rendered_outer_views() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let synth = run(&[
        "synth",
        "--out",
        s(&data),
        "--views",
        "4",
        "--towns",
        "Town01",
        "--weathers",
        "ClearNoon",
        "--frames",
        "2",
        "--width",
        "320",
        "--height",
        "192",
        "--focal",
        "160",
    ]);
    assert!(synth.status.success(), "{}", text(&synth));
    for frame in ["000000", "000001"] {
        let sample = data.join("Town01/ClearNoon").join(frame);
        oracle_reproduces_the_outer_views(&sample, &dir.path().join(frame), frame);
    }
}

/// Extrapolates cameras 1 and 2 of the synthetic `sample` (named `frame`)
/// with their exact disparities into `out`: the new cameras 0 and 3 match
/// the rendered ones on the warped pixels, and roughly in the holes.
fn oracle_reproduces_the_outer_views(sample: &Path, out: &Path, frame: &str) {
    let output = run(&[
        "extrapolate",
        "--left",
        s(&sample.join("rgb_1.png")),
        "--right",
        s(&sample.join("rgb_2.png")),
        "--left-disparity",
        s(&sample.join("gt/disp_1.pfm")),
        "--right-disparity",
        s(&sample.join("gt/disp_2.pfm")),
        "--out",
        s(out),
    ]);
    assert!(output.status.success(), "{}", text(&output));
    for (new, rendered, mask) in [
        ("image_1.png", "rgb_0.png", "mask_1.png"),
        ("image_4.png", "rgb_3.png", "mask_4.png"),
    ] {
        let ours = read_rgb(&out.join(new)).unwrap();
        let truth = read_rgb(&sample.join(rendered)).unwrap();
        let holes = read_mask(&out.join(mask)).unwrap();
        let kept = psnr(&ours, &truth, Some(&inverted(&holes))).unwrap();
        let filled = psnr(&ours, &truth, Some(&holes)).unwrap();
        let share =
            holes.as_raw().iter().filter(|m| **m != 0).count() as f64 / holes.as_raw().len() as f64;
        println!(
            "synthetic {frame} {new}: PSNR {kept:.2} dB on warped pixels, {filled:.2} dB on {:.1} % inpainted",
            100.0 * share
        );
        assert!(
            kept >= 30.0,
            "{frame} {new}: {kept:.2} dB on non-hole pixels"
        );
        assert!(filled > 12.0, "{frame} {new}: {filled:.2} dB on holes");
    }
}

#[test]
fn built_in_matcher_extrapolates_real_tsukuba_views() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let output = run(&[
        "extrapolate",
        "--left",
        s(&tsukuba(3)),
        "--right",
        s(&tsukuba(4)),
        "--max-disparity",
        "16",
        "--out",
        s(&out),
        "--preview",
    ]);
    assert!(output.status.success(), "{}", text(&output));
    let p2 = psnr(
        &read_rgb(&out.join("image_1.png")).unwrap(),
        &read_rgb(&tsukuba(2)).unwrap(),
        None,
    )
    .unwrap();
    let p5 = psnr(
        &read_rgb(&out.join("image_4.png")).unwrap(),
        &read_rgb(&tsukuba(5)).unwrap(),
        None,
    )
    .unwrap();
    println!("Tsukuba with the built-in SGM: col2 {p2:.2} dB, col5 {p5:.2} dB");
    assert!(p2 > 28.0 && p5 > 28.0, "col2 {p2:.2} dB, col5 {p5:.2} dB");
    let sheet = read_rgb(&out.join("preview.png")).unwrap();
    // Two rows of four 384x288 views under their captions, the colour bar
    // of the disparities below.
    assert_eq!(sheet.dimensions(), (1554, 707));
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["rig"]["num_views"], 4);
    assert_eq!(manifest["samples"][0]["views"][0], "image_1.png");
    assert_eq!(manifest["samples"][0]["synthesized_masks"][3], "mask_4.png");
}

#[test]
fn kitti_batch_reports_bad_frames_continues_and_writes_a_valid_manifest() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("training");
    let disp_dir = dir.path().join("disp");
    kitti_folder_with_broken_frames(&root, &disp_dir);
    let out = dir.path().join("out");
    let output = run(&[
        "extrapolate",
        "--kitti",
        s(&root),
        "--left-disparity-dir",
        s(&disp_dir),
        "--out",
        s(&out),
    ]);
    assert!(
        !output.status.success(),
        "broken frames give a non-zero exit"
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("1 done, 0 skipped, 4 failed"), "{stderr}");
    assert!(stderr.contains("not a rectified pair"), "{stderr}");
    assert!(stderr.contains("000002_10.png"), "{stderr}");
    assert!(
        stderr.contains("000003_10.pfm: 1 NaN or negative disparities"),
        "{stderr}"
    );
    assert!(
        stderr.contains("000004_10.pfm: disparity is (100, 50)"),
        "{stderr}"
    );
    assert!(out.join("image_4/000000_10.png").is_file());
    the_manifest_lists_the_finished_frame_and_validates(&out);
}

/// Tsukuba's col3 and col4 as five KITTI frames under `root`, with left
/// disparities in `disp_dir`: frame 0 whole, frame 1 smaller on the right
/// (not a rectified pair), frame 2 without its right view, frame 3 with a
/// NaN disparity and frame 4 with a disparity of another size.
fn kitti_folder_with_broken_frames(root: &Path, disp_dir: &Path) {
    let left = read_rgb(&tsukuba(3)).unwrap();
    let right = read_rgb(&tsukuba(4)).unwrap();
    let constant = FloatImage::from_pixel(384, 288, image::Luma([6.0]));
    for frame in [
        "000000_10",
        "000001_10",
        "000002_10",
        "000003_10",
        "000004_10",
    ] {
        write_rgb_png(&root.join("image_2").join(format!("{frame}.png")), &left).unwrap();
        if frame != "000002_10" {
            write_rgb_png(&root.join("image_3").join(format!("{frame}.png")), &right).unwrap();
        }
        let mut disparity = constant.clone();
        if frame == "000003_10" {
            disparity.put_pixel(10, 10, image::Luma([f32::NAN]));
        }
        if frame == "000004_10" {
            disparity = FloatImage::new(100, 50);
        }
        write_pfm_grey(
            &disp_dir.join(format!("{frame}.pfm")),
            &disparity,
            Endian::Little,
        )
        .unwrap();
    }
    // Frame 1 is smaller on the right: not a rectified pair.
    write_rgb_png(
        &root.join("image_3/000001_10.png"),
        &image::RgbImage::new(380, 288),
    )
    .unwrap();
}

/// The manifest in `out` lists only the finished frame, passes `validate
/// --deep`, and the folder stands alone: the input views are linked into
/// it.
fn the_manifest_lists_the_finished_frame_and_validates(out: &Path) {
    let manifest = out.join("manifest.json");
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    let samples = doc["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 1, "only the finished frame is listed");
    // The output folder stands alone: the input views are linked into it.
    assert_eq!(samples[0]["views"][1], "image_2/000000_10.png");
    assert!(out.join("image_3/000000_10.png").is_file());
    let check = run(&["validate", s(&manifest), "--deep"]);
    assert!(check.status.success(), "{}", text(&check));
}
