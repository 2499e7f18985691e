//! A monocular depth network through ONNX Runtime with its built-in card:
//! FastDepth (issue 60's test model, fetched by `tools/setup-depth-model.sh`,
//! which `tools/test.sh` runs; never committed) on real Middlebury Teddy.
//! Its depth, indoor-trained and 224x224, ranks Teddy's pixels as their
//! true disparity does. Without the model or the runtime these tests fail,
//! they never skip.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use mbs_core::formats::read_disparity;
use mbs_core::formats::rgb::read_rgb;
use mbs_infer::DepthKind;
use mbs_infer::onnx::{ModelCard, OnnxDepth, RuntimeOptions};

/// The model: `MBS_DEPTH_MODEL`, or where the set-up script puts it.
fn fastdepth() -> PathBuf {
    let path = std::env::var_os("MBS_DEPTH_MODEL").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.models/fastdepth_7.onnx"),
        PathBuf::from,
    );
    assert!(
        path.is_file(),
        "{} is missing: run tools/setup-depth-model.sh (tools/test.sh does)",
        path.display()
    );
    path
}

fn teddy(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/middlebury-teddy")
        .join(name)
}

/// Spearman's rank correlation of `a` and `b` (ties ranked by order).
fn spearman(a: &[f32], b: &[f32]) -> f64 {
    let ranks = |values: &[f32]| {
        let mut order: Vec<usize> = (0..values.len()).collect();
        order.sort_by(|&i, &j| values[i].total_cmp(&values[j]));
        let mut rank = vec![0.0; values.len()];
        for (r, i) in order.into_iter().enumerate() {
            rank[i] = r as f64;
        }
        rank
    };
    let (ra, rb) = (ranks(a), ranks(b));
    let n = a.len() as f64;
    let mean = (n - 1.0) / 2.0;
    let covariance: f64 = ra
        .iter()
        .zip(&rb)
        .map(|(x, y)| (x - mean) * (y - mean))
        .sum();
    let variance: f64 = ra.iter().map(|x| (x - mean) * (x - mean)).sum();
    covariance / variance
}

#[test]
fn fastdepth_ranks_teddy_as_its_true_disparity() {
    let card = ModelCard::load("fastdepth").unwrap();
    let model = OnnxDepth::open(&fastdepth(), card, &RuntimeOptions::default()).unwrap();
    let image = read_rgb(&teddy("im2.png")).unwrap();
    let depth = model.predict(&image).unwrap();
    assert_eq!(depth.kind, DepthKind::MetricDepth);
    assert_eq!(depth.values.dimensions(), image.dimensions());
    assert!(depth.values.iter().all(|d| d.is_finite() && *d > 0.0));
    // Teddy's quarter-size ground truth: 8-bit, 4 codes a pixel, 0 unknown.
    let truth = read_disparity(&teddy("disp2.png"), Some(4.0)).unwrap();
    let (inverse, disparity): (Vec<f32>, Vec<f32>) = depth
        .values
        .iter()
        .zip(truth.iter())
        .filter(|(_, t)| t.is_finite() && **t > 0.0)
        .map(|(d, t)| (1.0 / d, *t))
        .unzip();
    let rho = spearman(&inverse, &disparity);
    println!(
        "FastDepth on Teddy: Spearman {rho:.3} over {} pixels",
        inverse.len()
    );
    assert!(inverse.len() > 100_000, "{} pixels", inverse.len());
    assert!(rho > 0.8, "Spearman {rho}");
    // Indoor metres: Teddy's scene is about 1.5-3 m away; the network's
    // scale is NYU's, so only its order of magnitude is asserted.
    let mut sorted: Vec<f32> = depth.values.iter().copied().collect();
    sorted.sort_by(f32::total_cmp);
    let median = sorted[sorted.len() / 2];
    assert!((0.5..10.0).contains(&median), "median depth {median} m");
}

#[test]
fn a_stereo_card_is_refused_for_a_depth_model_and_a_depth_card_for_a_stereo_run() {
    let hitnet = ModelCard::load("hitnet").unwrap();
    let error = OnnxDepth::open(&fastdepth(), hitnet, &RuntimeOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("is a stereo card; this needs a monocular depth card"),
        "{error}"
    );
    let depth = ModelCard::load("fastdepth").unwrap();
    let error = mbs_infer::onnx::OnnxStereo::open(&fastdepth(), depth, &RuntimeOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("is a monocular depth card; this needs a stereo card"),
        "{error}"
    );
}
