//! End-to-end tests of `mbs-tool mono`: the geometry against `extrapolate`
//! on real Tsukuba views with their true disparity, the whole path with
//! FastDepth on real photos (deterministic, valid, trainable), a batch with
//! broken photos that resumes, and models that break their card.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::{Path, PathBuf};

use common::{SMALL, refused, run, text};
use mbs_core::FloatImage;
use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_core::formats::read_float_map;
use mbs_core::formats::rgb::{read_mask, read_rgb};
use mbs_image::quality::psnr;

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn testdata(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(name)
}

fn tsukuba(col: u32) -> PathBuf {
    testdata(&format!("middlebury-tsukuba-row3/scene1.row3.col{col}.ppm"))
}

/// FastDepth: `MBS_DEPTH_MODEL`, or where the set-up script puts it.
fn fastdepth() -> PathBuf {
    let path = std::env::var_os("MBS_DEPTH_MODEL")
        .map_or_else(|| testdata("../.models/fastdepth_7.onnx"), PathBuf::from);
    assert!(
        path.is_file(),
        "{} is missing: run tools/setup-depth-model.sh (tools/test.sh does)",
        path.display()
    );
    path
}

/// Tsukuba col3's true disparity of one column step (`+inf` where
/// unknown), times `steps`, written as a PFM in `dir`.
fn true_disparity(dir: &Path, steps: f32) -> PathBuf {
    let gt = image::open(testdata("middlebury-tsukuba-row3/truedisp.row3.col3.pgm"))
        .unwrap()
        .into_luma8();
    let map = FloatImage::from_fn(gt.width(), gt.height(), |x, y| {
        let v = gt.get_pixel(x, y).0[0];
        image::Luma([match v {
            0 => f32::INFINITY,
            v => steps * f32::from(v) / 16.0,
        }])
    });
    let path = dir.join(format!("disparity_x{steps}.pfm"));
    write_pfm_grey(&path, &map, Endian::Little).unwrap();
    path
}

/// Runs the command line `line` (words split at blanks: the test's paths
/// have none).
fn run_line(line: &str) -> std::process::Output {
    run(&line.split_whitespace().collect::<Vec<_>>())
}

/// Whether two image files hold the same pixels.
fn same_pixels(a: &Path, b: &Path) -> bool {
    read_rgb(a).unwrap() == read_rgb(b).unwrap()
}

/// Asserts that camera `camera` of the set in `set` and its mask are
/// `extrapolate`'s `image_{view}` and `mask_{view}` in `out`; returns the
/// view's PSNR against the real Tsukuba view.
fn same_view(set: &Path, camera: usize, out: &Path, view: &str) -> f64 {
    let ours = set.join(format!("image_{camera}/scene1.row3.col3.png"));
    let theirs = out.join(format!("image_{view}.png"));
    assert!(same_pixels(&ours, &theirs), "camera {camera}");
    let mask = read_mask(&set.join(format!("mask_{camera}/scene1.row3.col3.png"))).unwrap();
    assert_eq!(
        mask,
        read_mask(&out.join(format!("mask_{view}.png"))).unwrap()
    );
    let real = read_rgb(&tsukuba(camera as u32)).unwrap();
    psnr(&read_rgb(&ours).unwrap(), &real, None).unwrap()
}

#[test]
fn views_at_the_real_baselines_are_extrapolates_and_score_against_the_real_views() {
    let dir = tempfile::tempdir().unwrap();
    let once = true_disparity(dir.path(), 1.0);
    let twice = true_disparity(dir.path(), 2.0);
    let set = dir.path().join("set");
    let (col3, set_s) = (tsukuba(3), s(&set).to_string());
    let mono = run_line(&format!(
        "mono --image {} --depth {} --depth-kind disparity --views 5 --reference 2 --out {set_s}",
        s(&col3),
        s(&once)
    ));
    assert!(mono.status.success(), "{}", text(&mono));
    // extrapolate with col3 as both views of a pair: image_1 is one step
    // left of it, image_4 one step right; with twice the disparity, two.
    let mut scores = Vec::new();
    for (disparity, [left, right]) in [(&once, [2, 4]), (&twice, [1, 5])] {
        let out = dir.path().join(format!("extrapolated_{left}"));
        let (col3, d, out_s) = (s(&col3), s(disparity), s(&out));
        let extrapolate = run_line(&format!(
            "extrapolate --left {col3} --right {col3} --left-disparity {d} --right-disparity {d} --out {out_s}"
        ));
        assert!(extrapolate.status.success(), "{}", text(&extrapolate));
        for (camera, view) in [(left, "1"), (right, "4")] {
            scores.push((camera, same_view(&set, camera, &out, view)));
        }
    }
    eprintln!("PSNR of the synthesised Tsukuba views against the real ones: {scores:?}");
    // Measured: col2 30.34, col4 30.01, col1 26.88, col5 26.19 dB; the
    // floors sit 0.3 dB under.
    for (camera, score) in scores {
        let floor = match camera {
            2 => 30.04,
            4 => 29.71,
            1 => 26.58,
            _ => 25.89,
        };
        assert!(score > floor, "camera {camera}: {score} dB");
    }
}

/// `mono` on `photos` with FastDepth, `seed` and `jobs` worker threads
/// into `out`.
fn fastdepth_sets(photos: &Path, out: &Path, seed: &str, jobs: &str) {
    let output = run_line(&format!(
        "mono --images {} --model {} --card fastdepth --seed {seed} --jobs {jobs} --preview --out {}",
        s(photos),
        s(&fastdepth()),
        s(out)
    ));
    assert!(output.status.success(), "{}", text(&output));
}

/// Every file under `dir` but mbs's bookkeeping, by relative path, with
/// its bytes.
fn contents(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files: Vec<(PathBuf, Vec<u8>)> = walk(dir)
        .into_iter()
        .filter(|p| !p.file_name().unwrap().to_str().unwrap().starts_with(".mbs"))
        .map(|p| {
            (
                p.strip_prefix(dir).unwrap().to_path_buf(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .unwrap()
        .flat_map(|entry| {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path)
            } else {
                vec![path]
            }
        })
        .collect()
}

#[test]
fn fastdepth_sets_from_real_photos_are_deterministic_valid_and_train() {
    let dir = tempfile::tempdir().unwrap();
    let photos = dir.path().join("photos");
    std::fs::create_dir(&photos).unwrap();
    for (from, to) in [
        ("middlebury-teddy/im2.png", "teddy.png"),
        (
            "middlebury-tsukuba-row3/scene1.row3.col3.ppm",
            "tsukuba.ppm",
        ),
        ("middlebury-baby2/view1.png", "baby2.png"),
        ("middlebury-laundry/view1.png", "laundry.png"),
    ] {
        std::fs::copy(testdata(from), photos.join(to)).unwrap();
    }
    let (first, second, other) = (
        dir.path().join("a"),
        dir.path().join("b"),
        dir.path().join("c"),
    );
    fastdepth_sets(&photos, &first, "7", "2");
    fastdepth_sets(&photos, &second, "7", "1");
    fastdepth_sets(&photos, &other, "8", "2");
    let files = contents(&first);
    assert_eq!(files.len(), 4 * (4 + 3 + 1 + 1) + 1); // views, masks, PFM, preview; manifest
    assert!(
        files == contents(&second),
        "the same seed (with 1 and 2 threads) gave other bytes"
    );
    for id in ["teddy", "tsukuba", "baby2", "laundry"] {
        let pfm = format!("disparity_2/{id}.pfm");
        let a = read_float_map(&first.join(&pfm)).unwrap();
        assert_ne!(
            a,
            read_float_map(&other.join(&pfm)).unwrap(),
            "{id}: another seed, the same draw"
        );
        // The largest disparity of one baseline lies in the default
        // range, 0.05 to 0.15 of the width.
        let largest = a.iter().copied().fold(0.0f32, f32::max) / a.width() as f32;
        assert!((0.05..=0.15).contains(&largest), "{id}: {largest}");
    }
    the_manifest_says_how_and_trains(&first.join("manifest.json"), &dir.path().join("run"));
}

/// Asserts that the manifest `path` of FastDepth sets names the model,
/// card and seed, passes `validate --deep`, and that `train` runs S3 on it
/// into `run_dir`.
fn the_manifest_says_how_and_trains(path: &Path, run_dir: &Path) {
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let settings = &manifest["provenance"]["settings"];
    assert_eq!(settings["depth"]["model"], "fastdepth_7.onnx");
    assert_eq!(settings["depth"]["card"]["name"], "fastdepth");
    assert_eq!(settings["scaling"]["seed"], 7);
    let samples = manifest["samples"].as_array().unwrap();
    assert!(
        samples
            .iter()
            .all(|sample| sample["views"].as_array().unwrap().len() == 4)
    );
    let validate = run(&["validate", s(path), "--deep"]);
    assert!(validate.status.success(), "{}", text(&validate));
    let mut train = vec!["train", s(path), "--out", s(run_dir), "--steps", "2"];
    train.extend(["--val-every", "2"]);
    train.extend(SMALL);
    let trained = run(&train);
    assert!(trained.status.success(), "{}", text(&trained));
    let log = std::fs::read_to_string(run_dir.join("train.jsonl")).unwrap();
    let last: serde_json::Value = serde_json::from_str(log.lines().last().unwrap()).unwrap();
    assert_eq!(last["step"], 2, "{log}");
    assert!(last["loss"].as_f64().unwrap().is_finite(), "{log}");
}

/// Writes into `photos` an odd-sized photo and a good one (they work), a
/// grey and a 16-bit photo, and two more, and into `depths` depth maps by
/// id: one with a NaN value (nan) and none for `nodepth`.
fn broken_batch(photos: &Path, depths: &Path) {
    std::fs::create_dir_all(depths).unwrap();
    std::fs::create_dir_all(photos).unwrap();
    let teddy = read_rgb(&testdata("middlebury-teddy/im2.png")).unwrap();
    let odd = image::imageops::crop_imm(&teddy, 100, 100, 37, 21).to_image();
    for name in ["odd", "nan", "nodepth"] {
        odd.save(photos.join(format!("{name}.png"))).unwrap();
    }
    teddy.save(photos.join("good.png")).unwrap();
    let grey = image::imageops::grayscale(&teddy);
    grey.save(photos.join("grey.png")).unwrap();
    let deep = image::ImageBuffer::<image::Rgb<u16>, _>::from_pixel(40, 30, image::Rgb([9, 9, 9]));
    deep.save(photos.join("deep.png")).unwrap();
    let ramp = |(w, h): (u32, u32)| FloatImage::from_fn(w, h, |x, _| image::Luma([1.0 + x as f32]));
    let sizes = [((37, 21), "odd"), (teddy.dimensions(), "good")];
    let sizes = sizes
        .into_iter()
        .chain([(teddy.dimensions(), "grey"), ((40, 30), "deep")]);
    for (size, id) in sizes {
        let file = depths.join(format!("{id}.pfm"));
        write_pfm_grey(&file, &ramp(size), Endian::Little).unwrap();
    }
    let mut nan = ramp((37, 21));
    nan.put_pixel(3, 3, image::Luma([f32::NAN]));
    write_pfm_grey(&depths.join("nan.pfm"), &nan, Endian::Little).unwrap();
}

#[test]
fn a_batch_reports_broken_photos_goes_on_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let (photos, depths) = (dir.path().join("photos"), dir.path().join("depths"));
    broken_batch(&photos, &depths);
    let before = contents(dir.path());
    let out = dir.path().join("out");
    let line = format!(
        "mono --images {} --depth-dir {} --depth-kind inverse-relative --out {}",
        s(&photos),
        s(&depths),
        s(&out)
    );
    let first = run_line(&line);
    let reported = ["grey.png", "a grey image", "deep.png", "16 bits a channel"];
    refused(&first, &reported);
    let reported = ["nan.pfm", "NaN", "nodepth.png", "no depth file"];
    refused(&first, &reported);
    refused(&first, &["2 done, 0 skipped, 4 failed"]);
    // Nothing was written outside --out, and no input changed.
    let after: Vec<_> = contents(dir.path())
        .into_iter()
        .filter(|(p, _)| !p.starts_with("out"))
        .collect();
    assert!(
        after == before,
        "an input changed or a file appeared outside --out"
    );
    let validate = run(&["validate", s(&out.join("manifest.json")), "--deep"]);
    assert!(validate.status.success(), "{}", text(&validate));
    let manifest = std::fs::read_to_string(out.join("manifest.json")).unwrap();
    let ids = ["\"odd\"", "\"good\""];
    assert!(ids.iter().all(|id| manifest.contains(id)) && !manifest.contains("\"nan\""));
    // A second run skips what is done and fails the same photos again.
    refused(&run_line(&line), &["0 done, 2 skipped, 4 failed"]);
    an_output_over_an_input_is_refused(
        dir.path(),
        &photos.join("odd.png"),
        &depths.join("odd.pfm"),
    );
}

/// An output that would replace an input (the disparity PFM over the
/// depth file it is made from) is refused before anything is written.
fn an_output_over_an_input_is_refused(dir: &Path, photo: &Path, depth_file: &Path) {
    let inside = dir.join("inside");
    std::fs::create_dir_all(inside.join("disparity_2")).unwrap();
    let depth = inside.join("disparity_2/odd.pfm");
    std::fs::copy(depth_file, &depth).unwrap();
    let over = run_line(&format!(
        "mono --image {} --depth {} --depth-kind inverse-relative --out {}",
        s(photo),
        s(&depth),
        s(&inside)
    ));
    refused(&over, &["odd.pfm"]);
    assert_eq!(walk(&inside), std::slice::from_ref(&depth));
    assert_eq!(
        std::fs::read(&depth).unwrap(),
        std::fs::read(depth_file).unwrap()
    );
}

#[test]
fn models_that_break_their_card_are_refused_naming_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let card = testdata("onnx/depth_test.json");
    let photo = testdata("middlebury-teddy/im2.png");
    let mono = |model: &str, out: &str| {
        let model = testdata(&format!("onnx/{model}.onnx"));
        run_line(&format!(
            "mono --image {} --model {} --card {} --out {}",
            s(&photo),
            s(&model),
            s(&card),
            s(&dir.path().join(out))
        ))
    };
    let good = mono("depth_metric", "good");
    assert!(good.status.success(), "{}", text(&good));
    the_disparity_is_the_models_inverse_depth_scaled(&photo, &dir.path().join("good"));
    let refusals: [(&str, &[&str]); 3] = [
        (
            "depth_negative",
            &[
                "depth_negative.onnx",
                "zero or negative depth",
                "inverse-relative",
            ],
        ),
        ("depth_nan", &["depth_nan.onnx", "NaN"]),
        (
            "depth_half",
            &["depth_half.onnx", "expected a map of 450x375"],
        ),
    ];
    for (model, words) in refusals {
        refused(&mono(model, model), words);
        assert!(!dir.path().join(model).join("manifest.json").exists());
    }
    // A stereo network and card for a depth run are refused before
    // anything is written.
    let stereo = run_line(&format!(
        "mono --image {} --model {} --card {} --out {}",
        s(&photo),
        s(&testdata("onnx/stereo_dynamic.onnx")),
        s(&testdata("onnx/stereo_dynamic.json")),
        s(&dir.path().join("stereo"))
    ));
    refused(&stereo, &["stereo"]);
    assert!(!dir.path().join("stereo").exists());
}

/// depth_metric.onnx gives depth = 1 + the mean RGB in 0..1, so the
/// darkest pixel is the nearest: its disparity is the largest, the drawn
/// fraction of the width, and every other pixel's is in the ratio of their
/// inverse depths.
fn the_disparity_is_the_models_inverse_depth_scaled(photo: &Path, set: &Path) {
    let image = read_rgb(photo).unwrap();
    let depth =
        |p: &image::Rgb<u8>| 1.0 + p.0.iter().map(|&c| f32::from(c) / 255.0).sum::<f32>() / 3.0;
    let nearest = image.pixels().map(depth).fold(f32::INFINITY, f32::min);
    let disparity = read_float_map(&set.join("disparity_2/im2.pfm")).unwrap();
    let drawn = mbs_extrapolate::mono::draw_fraction(0.05, 0.15, 0, "im2");
    let largest = drawn * image.width() as f32;
    for (x, y) in [(0, 0), (200, 100), (449, 374)] {
        let expected = largest * nearest / depth(image.get_pixel(x, y));
        let found = disparity.get_pixel(x, y).0[0];
        assert!(
            (found - expected).abs() < 1e-3 * expected,
            "({x}, {y}): {found} vs {expected}"
        );
    }
}

#[test]
fn shards_share_a_folder_and_a_manifest_camera_is_a_photo_source() {
    let dir = tempfile::tempdir().unwrap();
    let (photos, depths) = (dir.path().join("photos"), dir.path().join("depths"));
    broken_batch(&photos, &depths);
    for name in ["grey", "deep", "nan", "nodepth"] {
        std::fs::remove_file(photos.join(format!("{name}.png"))).unwrap();
    }
    let out = dir.path().join("out");
    let line = format!(
        "mono --images {} --depth-dir {} --depth-kind inverse-relative --out {}",
        s(&photos),
        s(&depths),
        s(&out)
    );
    for shard in ["0/2", "1/2"] {
        let sharded = run_line(&format!("{line} --shard {shard}"));
        assert!(sharded.status.success(), "{}", text(&sharded));
        assert!(text(&sharded).contains("1 done"), "{}", text(&sharded));
    }
    assert!(!out.join("manifest.json").exists());
    let whole = run_line(&line);
    assert!(
        text(&whole).contains("0 done, 2 skipped, 0 failed"),
        "{}",
        text(&whole)
    );
    // The sets' camera 1 (the photos, linked) are photos of another run,
    // named by the samples' ids.
    let again = dir.path().join("again");
    let from_manifest = run_line(&format!(
        "mono --manifest {} --camera 1 --depth-dir {} --depth-kind inverse-relative --out {}",
        s(&out.join("manifest.json")),
        s(&depths),
        s(&again)
    ));
    assert!(from_manifest.status.success(), "{}", text(&from_manifest));
    for id in ["good", "odd"] {
        let view = format!("image_1/{id}.png");
        assert!(same_pixels(&out.join(&view), &again.join(&view)), "{id}");
    }
}
