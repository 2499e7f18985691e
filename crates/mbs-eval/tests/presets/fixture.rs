//! The presets' test data and their independent computations, shared by
//! mbs-eval's tests/presets.rs (the library's figures) and mbs-tool's
//! tests/protocols.rs (the binary's flags and output): Middlebury's Teddy
//! (testdata/, cropped to 448x372 so that its half size is whole) laid out
//! as KITTI 2015 and 2012, MiddEval3, ETH3D, DrivingStereo and SceneFlow
//! folders, each with a second frame whose disparities are 4 times Teddy's
//! (above 191 in places), and predictions made from the ground truth with
//! errors of every size, holes (NaN, +inf), negative values and values
//! beyond the image; and each preset's figures computed from its project's
//! code (not from the library's).

#![allow(dead_code)] // each test file uses a different subset

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use mbs_core::formats::{pfm, png16, read_disparity, rgb};
use mbs_core::{FloatImage, MaskImage};
use serde_json::Value;

pub const WIDTH: u32 = 448;
pub const HEIGHT: u32 = 372;

/// The presets, as `--protocol` names them.
pub const PRESETS: [&str; 7] = [
    "pixels",
    "s3",
    "raft-stereo",
    "igev-stereo",
    "kitti",
    "eth3d",
    "middlebury",
];

pub fn teddy(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/middlebury-teddy")
        .join(file)
}

/// Teddy's left-view ground truth (disp2.png / 4, `inf` unknown), cropped,
/// times `gain`.
pub fn teddy_truth(gain: f32) -> FloatImage {
    let gt = read_disparity(&teddy("disp2.png"), Some(4.0)).unwrap();
    let mut gt = image::imageops::crop_imm(&gt, 0, 0, WIDTH, HEIGHT).to_image();
    gt.iter_mut().for_each(|d| *d *= gain);
    gt
}

/// Saves Teddy's view `file`, cropped, as `path`.
pub fn teddy_view(file: &str, path: &Path) {
    let view = image::open(teddy(file)).unwrap().into_rgb8();
    let view = image::imageops::crop_imm(&view, 0, 0, WIDTH, HEIGHT).to_image();
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    view.save(path).unwrap();
}

/// A prediction from `gt`: mostly small errors (a cubic spread up to
/// 3 + 1.7 `seed` px), 3 % NaN, 1 % +inf, 1 % at -5 and 0.5 % at 1000 px
/// (beyond the image); 20 px where the ground truth is unknown. `seed`
/// varies it.
pub fn predicted(gt: &FloatImage, seed: u32) -> FloatImage {
    FloatImage::from_fn(gt.width(), gt.height(), |x, y| {
        let mut h = x.wrapping_mul(0x9E37_79B1) ^ y.wrapping_mul(0x85EB_CA77) ^ seed;
        h = (h ^ (h >> 15)).wrapping_mul(0x2C1B_3C6D);
        h = (h ^ (h >> 12)) % 1000;
        let g = gt.get_pixel(x, y).0[0];
        let base = if g.is_finite() { g } else { 20.0 };
        let t = ((h % 97) as f32 - 48.0) / 48.0;
        let d = match h {
            0..30 => f32::NAN,
            30..40 => f32::INFINITY,
            40..50 => -5.0,
            50..55 => 1000.0,
            _ => base + (3.0 + 1.7 * seed as f32) * t * t * t,
        };
        image::Luma([d])
    })
}

/// One frame as the computations here see it.
pub struct Frame {
    /// The frame's name (the pair id).
    pub name: String,
    /// Ground truth, `inf` unknown.
    pub gt: FloatImage,
    /// Non-occluded (Middlebury/ETH3D mask 255; KITTI disp_noc valid).
    pub noc: Option<Vec<bool>>,
    /// The prediction scored (Middlebury's may be half size).
    pub pred: FloatImage,
    /// The scene's calib.txt ndisp.
    pub ndisp: Option<f32>,
}

/// Non-occluded: known ground truth right of column 100.
pub fn noc_of(gt: &FloatImage) -> Vec<bool> {
    gt.enumerate_pixels()
        .map(|(x, _, d)| d.0[0].is_finite() && x >= 100)
        .collect()
}

/// A benchmark folder laid out for the tests.
pub struct Layout {
    /// The folder's flag (`--kitti`, ...).
    pub flag: &'static str,
    /// The folder.
    pub dir: PathBuf,
    /// The dataset, as the presets' rules name it.
    pub dataset: &'static str,
    /// Its scored frames.
    pub frames: Vec<Frame>,
    /// Their predictions, `<name>.pfm`.
    pub predictions: PathBuf,
}

/// Two frames of Teddy, named `names`, with predictions: the second's
/// disparities 4 times Teddy's, and unknown in its top 80 rows (so that the
/// frames differ in size and error).
pub fn frames(names: [&str; 2], masked: bool) -> Vec<Frame> {
    names
        .iter()
        .zip([1.0, 4.0])
        .enumerate()
        .map(|(k, (name, gain))| {
            let mut gt = teddy_truth(gain);
            for (_, y, d) in gt.enumerate_pixels_mut() {
                if k == 1 && y < 80 {
                    d.0[0] = f32::INFINITY;
                }
            }
            Frame {
                name: name.to_string(),
                noc: masked.then(|| noc_of(&gt)),
                pred: predicted(&gt, k as u32 + 1),
                gt,
                ndisp: None,
            }
        })
        .collect()
}

/// Writes each frame's prediction into `dir` as `<name>.pfm`.
pub fn write_predictions(dir: &Path, frames: &[Frame]) {
    for f in frames {
        let path = dir.join(format!("{}.pfm", f.name));
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        pfm::write_pfm_grey(&path, &f.pred, pfm::Endian::Little).unwrap();
    }
}

/// A KITTI training folder of `year` (2015 or 2012) under `root`: frames
/// 000000_10 and 000001_10 with ground truth, 000002_10 with views only and
/// 000003_10 whose ground truth is a folder.
pub fn kitti_layout(root: &Path, year: u32) -> Layout {
    let dir = root.join(format!("kitti{year}/training"));
    let (views, occ, noc) = match year {
        2015 => (["image_2", "image_3"], "disp_occ_0", "disp_noc_0"),
        _ => (["colored_0", "colored_1"], "disp_occ", "disp_noc"),
    };
    let frames = frames(["000000_10", "000001_10"], true);
    for name in ["000000_10", "000001_10", "000002_10", "000003_10"] {
        teddy_view("im2.png", &dir.join(views[0]).join(format!("{name}.png")));
        teddy_view("im6.png", &dir.join(views[1]).join(format!("{name}.png")));
    }
    for f in &frames {
        let file = format!("{}.png", f.name);
        png16::write_kitti_disparity(&dir.join(occ).join(&file), &f.gt).unwrap();
        let mut noc_map = f.gt.clone();
        for (x, _, d) in noc_map.enumerate_pixels_mut() {
            if x < 100 {
                d.0[0] = f32::INFINITY;
            }
        }
        png16::write_kitti_disparity(&dir.join(noc).join(&file), &noc_map).unwrap();
    }
    std::fs::create_dir_all(dir.join(occ).join("000003_10.png")).unwrap();
    let predictions = root.join(format!("pred-kitti{year}"));
    write_predictions(&predictions, &frames);
    let dataset = if year == 2015 {
        "KITTI 2015"
    } else {
        "KITTI 2012"
    };
    Layout {
        flag: "--kitti",
        dir,
        dataset,
        frames,
        predictions,
    }
}

/// A two-view scene: views in `scene`, ground truth and mask0nocc.png
/// (255 non-occluded, 128 occluded, 0 unknown) in `truth`.
pub fn two_view_scene(scene: &Path, truth: &Path, gt: &FloatImage) {
    teddy_view("im2.png", &scene.join("im0.png"));
    teddy_view("im6.png", &scene.join("im1.png"));
    std::fs::create_dir_all(truth).unwrap();
    pfm::write_pfm_grey(&truth.join("disp0GT.pfm"), gt, pfm::Endian::Little).unwrap();
    let mask = MaskImage::from_fn(WIDTH, HEIGHT, |x, y| {
        let level = match (gt.get_pixel(x, y).0[0].is_finite(), x < 100) {
            (false, _) => 0,
            (true, true) => 128,
            (true, false) => 255,
        };
        image::Luma([level])
    });
    rgb::write_mask_png(&truth.join("mask0nocc.png"), &mask).unwrap();
}

/// MiddEval3 `trainingH`: Teddy (calib.txt ndisp=60) and Teddy4 (no
/// calib.txt), NoTruth (views only) and Fifo (its disp0GT.pfm a FIFO).
pub fn middlebury_layout(root: &Path) -> Layout {
    let dir = root.join("MiddEval3/trainingH");
    let mut frames = frames(["Teddy", "Teddy4"], true);
    frames[0].ndisp = Some(60.0);
    for f in &frames {
        two_view_scene(&dir.join(&f.name), &dir.join(&f.name), &f.gt);
    }
    std::fs::write(
        dir.join("Teddy/calib.txt"),
        "cam0=[375 0 100; 0 375 90; 0 0 1]\nbaseline=160\nwidth=448\nheight=372\nndisp=60\n",
    )
    .unwrap();
    for scene in ["NoTruth", "Fifo"] {
        teddy_view("im2.png", &dir.join(scene).join("im0.png"));
        teddy_view("im6.png", &dir.join(scene).join("im1.png"));
    }
    let fifo = dir.join("Fifo/disp0GT.pfm");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    assert!(made.unwrap().success());
    let predictions = root.join("pred-middlebury");
    write_predictions(&predictions, &frames);
    Layout {
        flag: "--middlebury",
        dir,
        dataset: "Middlebury",
        frames,
        predictions,
    }
}

/// ETH3D `two_view_training` with its ground truth in `two_view_training_gt`.
pub fn eth3d_layout(root: &Path) -> Layout {
    let dir = root.join("two_view_training");
    let frames = frames(["delivery_area_1l", "teddy4"], true);
    for f in &frames {
        let truth = root.join("two_view_training_gt").join(&f.name);
        two_view_scene(&dir.join(&f.name), &truth, &f.gt);
    }
    let predictions = root.join("pred-eth3d");
    write_predictions(&predictions, &frames);
    Layout {
        flag: "--eth3d",
        dir,
        dataset: "ETH3D",
        frames,
        predictions,
    }
}

/// A DrivingStereo weather folder at half size.
pub fn driving_stereo_layout(root: &Path) -> Layout {
    let dir = root.join("DrivingStereo/sunny");
    let frames = frames(
        [
            "2018-10-19-09-30-39_2018-10-19-09-51-11-408",
            "2018-10-19-09-30-39_2018-10-19-09-51-11-509",
        ],
        false,
    );
    for f in &frames {
        let file = format!("{}.png", f.name);
        teddy_view("im2.png", &dir.join("left-image-half-size").join(&file));
        teddy_view("im6.png", &dir.join("right-image-half-size").join(&file));
        let gt = dir.join("disparity-map-half-size").join(&file);
        std::fs::create_dir_all(gt.parent().unwrap()).unwrap();
        png16::write_kitti_disparity(&gt, &f.gt).unwrap();
    }
    let predictions = root.join("pred-drivingstereo");
    write_predictions(&predictions, &frames);
    Layout {
        flag: "--drivingstereo",
        dir,
        dataset: "DrivingStereo",
        frames,
        predictions,
    }
}

/// A FlyingThings3D test folder: frames TEST/A/0000/0006 and 0007.
pub fn scene_flow_layout(root: &Path) -> Layout {
    let dir = root.join("flyingthings3d");
    let frames = frames(["TEST/A/0000/0006", "TEST/A/0000/0007"], false);
    for f in &frames {
        let file = f.name.rsplit('/').next().unwrap();
        let pass = dir.join("frames_cleanpass/TEST/A/0000");
        teddy_view("im2.png", &pass.join("left").join(format!("{file}.png")));
        teddy_view("im6.png", &pass.join("right").join(format!("{file}.png")));
        let truth = dir.join("disparity/TEST/A/0000/left");
        std::fs::create_dir_all(&truth).unwrap();
        let path = truth.join(format!("{file}.pfm"));
        pfm::write_pfm_grey(&path, &f.gt, pfm::Endian::Little).unwrap();
    }
    let predictions = root.join("pred-sceneflow");
    write_predictions(&predictions, &frames);
    Layout {
        flag: "--sceneflow",
        dir,
        dataset: "SceneFlow",
        frames,
        predictions,
    }
}

// ---------------------------------------------------------------------
// The presets' rules, computed here from each project's code.
// ---------------------------------------------------------------------

/// A preset's figures: its headline's JSON key, the headline per region
/// and the EPE of its first region.
#[derive(Debug, Clone, PartialEq)]
pub struct Scores {
    pub key: String,
    pub regions: BTreeMap<&'static str, f64>,
    pub epe: Option<f64>,
}

/// The regions of a pixel: (ALL, NOC, OCC), given its validity.
pub fn regions(frame: &Frame, i: usize, valid: bool) -> [bool; 3] {
    let noc = frame.noc.as_ref().is_some_and(|n| n[i]);
    [valid, valid && noc, valid && !noc]
}

pub const REGION_NAMES: [&str; 3] = ["ALL", "NOC", "OCC"];

/// mbs's pixels: finite ground truth, pooled over the pixels of every
/// image; a missing prediction is an outlier left out of EPE.
pub fn pixels(frames: &[Frame], threshold: f32) -> Scores {
    let (mut n, mut bad) = ([0u64; 3], [0u64; 3]);
    let (mut sum, mut predicted) = (0f64, 0u64);
    for f in frames {
        for (i, (&g, &d)) in f.gt.as_raw().iter().zip(f.pred.as_raw()).enumerate() {
            for (r, inside) in regions(f, i, g.is_finite()).into_iter().enumerate() {
                if !inside {
                    continue;
                }
                n[r] += 1;
                let err = (d - g).abs();
                bad[r] += u64::from(!d.is_finite() || err > threshold);
                if r == 0 && d.is_finite() {
                    sum += f64::from(err);
                    predicted += 1;
                }
            }
        }
    }
    let masked = frames.iter().any(|f| f.noc.is_some());
    let regions = (0..if masked { 3 } else { 1 })
        .map(|r| (REGION_NAMES[r], 100.0 * bad[r] as f64 / n[r] as f64))
        .collect();
    Scores {
        key: format!("out{threshold}"),
        regions,
        epe: Some(sum / predicted as f64),
    }
}

/// stereo_toolbox generalization_eval.py:32-58: all = 0 < gt < 191, noc =
/// all & mask, occ = all & !noc; per image percentages, each region its own
/// image counter; EPE the per-image mean over all. (A missing prediction:
/// an outlier left out of the EPE, mbs's documented choice.)
pub fn s3(frames: &[Frame], threshold: f32) -> Scores {
    let mut metrics = [0f64; 4]; // epe, occ, noc, all
    let mut image_num = [0u32; 4];
    for f in frames {
        let gt = f.gt.as_raw();
        let all: Vec<bool> = gt.iter().map(|&g| g > 0.0 && g < 191.0).collect();
        let nocm: Vec<bool> = (0..gt.len())
            .map(|i| all[i] && f.noc.as_ref().is_some_and(|n| n[i]))
            .collect();
        let occm: Vec<bool> = (0..gt.len()).map(|i| all[i] && !nocm[i]).collect();
        let err: Vec<f32> = gt
            .iter()
            .zip(f.pred.as_raw())
            .map(|(g, d)| (d - g).abs())
            .collect();
        let finite: Vec<f32> = (0..gt.len())
            .filter(|&i| all[i] && err[i].is_finite())
            .map(|i| err[i])
            .collect();
        if !finite.is_empty() {
            metrics[0] += finite.iter().map(|&e| f64::from(e)).sum::<f64>() / finite.len() as f64;
            image_num[0] += 1;
        }
        for (k, mask) in [(1, &occm), (2, &nocm), (3, &all)] {
            let num = mask.iter().filter(|&&m| m).count();
            if num > 0 {
                let bad = (0..gt.len())
                    .filter(|&i| mask[i] && (err[i].is_nan() || err[i] > threshold))
                    .count();
                metrics[k] += bad as f64 / num as f64 * 100.0;
                image_num[k] += 1;
            }
        }
    }
    let mut regions = BTreeMap::new();
    for (k, name) in [(3, "ALL"), (2, "NOC"), (1, "OCC")] {
        if image_num[k] > 0 && (k == 3 || frames.iter().any(|f| f.noc.is_some())) {
            regions.insert(name, metrics[k] / f64::from(image_num[k]));
        }
    }
    Scores {
        key: format!("out{threshold}"),
        regions,
        epe: Some(metrics[0] / f64::from(image_num[0])),
    }
}

/// RAFT-Stereo's and IGEV-Stereo's evaluate_stereo.py: `val` pixels of each
/// image (`noc`: and mask0nocc == 255), out = epe > threshold; EPE the
/// mean of the per-image means; D1 `pooled` (np.concatenate of out_list)
/// or the mean of the per-image means.
pub fn network(
    frames: &[Frame],
    val: fn(f32) -> bool,
    noc: bool,
    threshold: f32,
    pooled: bool,
) -> Scores {
    let (mut epe_list, mut out_list) = (Vec::new(), Vec::new());
    let (mut out_all, mut n_all) = (0u64, 0u64);
    for f in frames {
        let (mut n, mut out, mut sum, mut predicted) = (0u64, 0u64, 0f64, 0u64);
        for (i, (&g, &d)) in f.gt.as_raw().iter().zip(f.pred.as_raw()).enumerate() {
            let masked = !noc || f.noc.as_ref().unwrap()[i];
            if !(g.is_finite() && val(g) && masked) {
                continue;
            }
            let epe = (d - g).abs();
            n += 1;
            out += u64::from(!d.is_finite() || epe > threshold);
            if d.is_finite() {
                sum += f64::from(epe);
                predicted += 1;
            }
        }
        if n == 0 {
            continue;
        }
        epe_list.push(sum / predicted as f64);
        out_list.push(out as f64 / n as f64);
        out_all += out;
        n_all += n;
    }
    let d1 = if pooled {
        100.0 * out_all as f64 / n_all as f64
    } else {
        100.0 * out_list.iter().sum::<f64>() / out_list.len() as f64
    };
    let region = if noc { "NOC" } else { "ALL" };
    Scores {
        key: format!("out{threshold}"),
        regions: BTreeMap::from([(region, d1)]),
        epe: Some(epe_list.iter().sum::<f64>() / epe_list.len() as f64),
    }
}

/// io_disp.h `interpolateBackground()`, on the devkit's own encoding: a
/// PNG value 0 (a value not finite, or whose code `round(d * 256)` is
/// below 1) is -1.
pub fn interpolate_background(pred: &FloatImage) -> Vec<f32> {
    let (w, h) = (pred.width() as i32, pred.height() as i32);
    let mut data: Vec<f32> = pred
        .as_raw()
        .iter()
        .map(|&d| {
            if d.is_finite() && (d * 256.0).round() >= 1.0 {
                d
            } else {
                -1.0
            }
        })
        .collect();
    let at = |u: i32, v: i32| (v * w + u) as usize;
    for v in 0..h {
        let mut count = 0;
        for u in 0..w {
            if data[at(u, v)] >= 0.0 {
                if count >= 1 {
                    let (u1, u2) = (u - count, u - 1);
                    if u1 > 0 && u2 < w - 1 {
                        let d_ipol = data[at(u1 - 1, v)].min(data[at(u2 + 1, v)]);
                        for u_curr in u1..=u2 {
                            data[at(u_curr, v)] = d_ipol;
                        }
                    }
                }
                count = 0;
            } else {
                count += 1;
            }
        }
        if let Some(u) = (0..w).find(|&u| data[at(u, v)] >= 0.0) {
            for u2 in 0..u {
                data[at(u2, v)] = data[at(u, v)];
            }
        }
        if let Some(u) = (0..w).rev().find(|&u| data[at(u, v)] >= 0.0) {
            for u2 in u + 1..w {
                data[at(u2, v)] = data[at(u, v)];
            }
        }
    }
    for u in 0..w {
        if let Some(v) = (0..h).find(|&v| data[at(u, v)] >= 0.0) {
            for v2 in 0..v {
                data[at(u, v2)] = data[at(u, v)];
            }
        }
        if let Some(v) = (0..h).rev().find(|&v| data[at(u, v)] >= 0.0) {
            for v2 in v + 1..h {
                data[at(u, v2)] = data[at(u, v)];
            }
        }
    }
    data
}

/// The KITTI 2015 devkit (evaluate_scene_flow.cpp): D1 = error above 3 px
/// and above 5 % of the ground truth, against the interpolated prediction,
/// counts summed over the images; no EPE. 2012 (evaluate_stereo.cpp):
/// Out-3 per image, averaged (statMean), and the per-image mean error,
/// averaged.
pub fn kitti(frames: &[Frame], year: u32) -> Scores {
    let (mut bad, mut n) = ([0u64; 3], [0u64; 3]);
    let (mut out_mean, mut avg_mean) = ([0f64; 3], 0f64);
    for f in frames {
        let ipol = interpolate_background(&f.pred);
        let (mut image_bad, mut image_n, mut err_sum) = ([0u64; 3], [0u64; 3], 0f64);
        for (i, &d_gt) in f.gt.as_raw().iter().enumerate() {
            let d_err = (d_gt - ipol[i]).abs();
            let outlier = match year {
                2015 => d_err > 3.0 && f64::from(d_err / d_gt.abs()) > 0.05,
                _ => d_err > 3.0,
            };
            for (r, inside) in regions(f, i, d_gt.is_finite()).into_iter().enumerate() {
                if inside {
                    image_n[r] += 1;
                    image_bad[r] += u64::from(outlier);
                    if r == 0 {
                        err_sum += f64::from(d_err);
                    }
                }
            }
        }
        for r in 0..3 {
            bad[r] += image_bad[r];
            n[r] += image_n[r];
            out_mean[r] += image_bad[r] as f64 / image_n[r] as f64 / frames.len() as f64;
        }
        avg_mean += err_sum / image_n[0] as f64 / frames.len() as f64;
    }
    let regions = (0..3).map(|r| match year {
        2015 => (REGION_NAMES[r], 100.0 * bad[r] as f64 / n[r] as f64),
        _ => (REGION_NAMES[r], 100.0 * out_mean[r]),
    });
    Scores {
        key: if year == 2015 { "d1" } else { "out3" }.into(),
        regions: regions.collect(),
        epe: (year == 2012).then_some(avg_mean),
    }
}

/// ETH3D's ComputeMetrics (main.cc:349-490): over the estimated pixels
/// (finite, within ± the width), bad-1.0 and avgerr per image (nothing
/// estimated: bad 1), here averaged over the images.
pub fn eth3d(frames: &[Frame]) -> Scores {
    let (mut bad_sum, mut avg_sum, mut avg_images) = ([0f64; 3], 0f64, 0u32);
    for f in frames {
        let width = f.gt.width() as f32;
        let (mut bad, mut estimated, mut error_sum) = ([0u64; 3], [0u64; 3], 0f64);
        for (i, (&g, &d)) in f.gt.as_raw().iter().zip(f.pred.as_raw()).enumerate() {
            if d.is_nan() || !d.is_finite() || d > width || d < -width {
                continue;
            }
            let abs_error = (d - g).abs();
            for (r, inside) in regions(f, i, g.is_finite()).into_iter().enumerate() {
                if inside {
                    estimated[r] += 1;
                    bad[r] += u64::from(abs_error > 1.0);
                    if r == 0 {
                        error_sum += f64::from(abs_error);
                    }
                }
            }
        }
        for r in 0..3 {
            bad_sum[r] += match estimated[r] {
                0 => 1.0,
                n => bad[r] as f64 / n as f64,
            };
        }
        if estimated[0] > 0 {
            avg_sum += error_sum / estimated[0] as f64;
            avg_images += 1;
        }
    }
    let count = frames.len() as f64;
    Scores {
        key: "out1".into(),
        regions: (0..3)
            .map(|r| (REGION_NAMES[r], 100.0 * bad_sum[r] / count))
            .collect(),
        epe: Some(avg_sum / f64::from(avg_images)),
    }
}

/// MiddEval3's evaldisp.cpp: scale = GT width / disp width, d = scale *
/// disp(x / scale, y / scale), +inf invalid (NaN too, here), valid clipped
/// to [0, scale * maxdisp]; total-bad = (bad + invalid) / n at 2 px;
/// avgErr = serr / (n - invalid); here averaged over the images.
pub fn evaldisp(frames: &[Frame]) -> Scores {
    let (mut totbad, mut avg) = ([0f64; 3], 0f64);
    for f in frames {
        let scale = f.gt.width() / f.pred.width();
        let maxd = f.ndisp.unwrap_or(scale as f32 * 99999.0);
        let (mut n, mut bad, mut invalid, mut serr) = ([0u64; 3], [0u64; 3], [0u64; 3], 0f64);
        for (x, y, gt) in f.gt.enumerate_pixels() {
            let gt = gt.0[0];
            if gt == f32::INFINITY {
                continue;
            }
            let mut d = scale as f32 * f.pred.get_pixel(x / scale, y / scale).0[0];
            let valid = d != f32::INFINITY && !d.is_nan();
            if valid {
                d = 0f32.max(maxd.min(d));
            }
            let err = (d - gt).abs();
            let i = (y * f.gt.width() + x) as usize;
            for (r, inside) in regions(f, i, true).into_iter().enumerate() {
                if inside {
                    n[r] += 1;
                    if valid {
                        bad[r] += u64::from(err > 2.0);
                        if r == 0 {
                            serr += f64::from(err);
                        }
                    } else {
                        invalid[r] += 1;
                    }
                }
            }
        }
        for r in 0..3 {
            totbad[r] += 100.0 * (bad[r] + invalid[r]) as f64 / n[r] as f64 / frames.len() as f64;
        }
        avg += serr / (n[0] - invalid[0]) as f64 / frames.len() as f64;
    }
    Scores {
        key: "out2".into(),
        regions: (0..3).map(|r| (REGION_NAMES[r], totbad[r])).collect(),
        epe: Some(avg),
    }
}

/// The preset's figures on `layout`'s frames, computed here; `None` where
/// the preset has no rules for the dataset.
pub fn expected(preset: &str, layout: &Layout) -> Option<Scores> {
    let frames = &layout.frames;
    let customary = match layout.dataset {
        "KITTI 2015" | "KITTI 2012" | "DrivingStereo" => 3.0,
        "Middlebury" => 2.0,
        _ => 1.0,
    };
    Some(match (preset, layout.dataset) {
        ("pixels", _) => pixels(frames, customary),
        ("s3", _) => s3(frames, customary),
        ("raft-stereo", "DrivingStereo") | ("igev-stereo", "DrivingStereo") => return None,
        ("raft-stereo", "ETH3D") => network(frames, |g| g.abs() < 512.0, false, 1.0, false),
        ("raft-stereo", "Middlebury") => network(frames, |g| g < 1000.0, false, 2.0, false),
        ("raft-stereo", "SceneFlow") => network(frames, |g| g.abs() < 192.0, false, 1.0, true),
        ("raft-stereo", _) => network(frames, |g| g > 0.0, false, 3.0, true),
        ("igev-stereo", "ETH3D") => network(frames, |g| g < 512.0, true, 1.0, false),
        ("igev-stereo", "Middlebury") => network(frames, |g| g < 192.0, true, 2.0, false),
        ("igev-stereo", "SceneFlow") => network(frames, |g| g.abs() < 192.0, false, 3.0, true),
        ("igev-stereo", _) => network(frames, |g| g > 0.0 && g < 192.0, false, 3.0, true),
        ("kitti", "KITTI 2015") => kitti(frames, 2015),
        ("kitti", "KITTI 2012") => kitti(frames, 2012),
        ("eth3d", "ETH3D") => eth3d(frames),
        ("middlebury", "Middlebury") => evaldisp(frames),
        _ => return None,
    })
}

/// The figures `eval --json` reports under `preset` (pixels: pooled, at
/// `key`; the others: the protocol's headline).
pub fn reported(json: &Value, preset: &str, pixels_key: &str) -> Scores {
    let (key, set) = match preset {
        "pixels" => (pixels_key.to_string(), &json["pooled"]),
        _ => (
            json["headline"].as_str().unwrap().to_string(),
            &json["score"],
        ),
    };
    let regions: BTreeMap<&'static str, f64> = REGION_NAMES
        .into_iter()
        .filter_map(|r| Some((r, set.get(r)?[&key].as_f64().unwrap())))
        .collect();
    let first = REGION_NAMES.into_iter().find_map(|r| set.get(r)).unwrap();
    Scores {
        epe: first["epe"].as_f64(),
        key,
        regions,
    }
}

/// Whether two figures agree to 1e-6.
pub fn agree(a: &Scores, b: &Scores) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-6;
    a.key == b.key
        && a.regions.len() == b.regions.len()
        && a.regions
            .iter()
            .all(|(r, v)| b.regions.get(r).is_some_and(|w| close(*v, *w)))
        && match (a.epe, b.epe) {
            (Some(x), Some(y)) => close(x, y),
            (x, y) => x == y,
        }
}
