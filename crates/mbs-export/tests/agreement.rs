//! Exported models run through ONNX Runtime and agree with mbs's own
//! forward pass on a real Middlebury pair.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::sync::{Mutex, PoisonError};

use burn::module::Module;
use mbs_core::Side;
use mbs_infer::StereoMatcher;
use mbs_infer::onnx::ModelCard;
use mbs_infer::onnx::runtime::RuntimeOptions;
use mbs_infer::onnx::stereo::OnnxStereo;
use mbs_nets::inference::predict_image;
use mbs_nets::network::{BackboneKind, NetworkConfig};

/// burn's CPU random generator is one per process: each test seeds it and
/// draws its network under this lock, so that its weights do not depend on
/// the other tests running beside it. Unseeded, a random network sometimes
/// predicts only negative disparities, which `predict --model` marks
/// invalid, and the test had nothing to compare.
static WEIGHT_DRAWING: Mutex<()> = Mutex::new(());

fn teddy(width: u32, height: u32) -> (image::RgbImage, image::RgbImage) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/middlebury-teddy");
    let read = |name: &str| {
        let image = image::open(root.join(name)).unwrap().to_rgb8();
        image::imageops::resize(&image, width, height, image::imageops::FilterType::Triangle)
    };
    (read("im2.png"), read("im6.png"))
}

/// The largest and mean absolute difference between `kind`'s forward pass
/// and its ONNX export through ONNX Runtime, on Teddy at `height` x `width`.
fn difference(
    kind: BackboneKind,
    overrides: &[&str],
    height: usize,
    width: usize,
    opset: i64,
) -> (f32, f32) {
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    let config = NetworkConfig::with_overrides(kind, &overrides).unwrap();
    let device = burn::tensor::Device::flex();
    let drawing = WEIGHT_DRAWING
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    device.seed(7);
    let fresh = config.init(&device).unwrap();
    // burn draws a parameter when it is first used: moving the network
    // while a clone shares its parameters draws them all here, under the lock.
    let network = fresh.clone().to_device(&device);
    drop(fresh);
    drop(drawing);
    let export = mbs_export::Export {
        height,
        width,
        opset,
        metadata: &[],
    };
    let bytes = mbs_export::onnx_model(&network, &export).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("net.onnx");
    std::fs::write(&path, &bytes).unwrap();
    // The card as `export` writes it, read back and checked as `--card` reads it.
    let card = mbs_export::stereo_card("test", "", height, width);
    let card = ModelCard::from_json("test", &serde_json::to_string(&card).unwrap()).unwrap();
    let onnx = OnnxStereo::open(&path, card, &RuntimeOptions::default()).unwrap();
    let (left, right) = teddy(width as u32, height as u32);
    let ours = predict_image(&network, &left, &right, Side::Right, &device).unwrap();
    let theirs = onnx.predict(&left, &right).unwrap();
    // `predict --model` marks a negative disparity invalid (infinite), as
    // for any ONNX stereo model; random weights predict some.
    let differences: Vec<f32> = ours
        .as_raw()
        .iter()
        .zip(theirs.disparity.as_raw())
        .filter(|(a, b)| {
            assert!(**a >= 0.0 || b.is_infinite(), "{a} became {b}");
            **a >= 0.0
        })
        .map(|(a, b)| (a - b).abs())
        .collect();
    println!(
        "{} of {} pixels compared",
        differences.len(),
        ours.as_raw().len()
    );
    let largest = differences.iter().copied().fold(0.0, f32::max);
    let mean = differences.iter().sum::<f32>() / differences.len() as f32;
    println!(
        "{kind:?} at {height}x{width}, opset {opset}: {} bytes, largest {largest:e}, mean {mean:e} px",
        bytes.len()
    );
    (largest, mean)
}

#[test]
fn the_compact_network_agrees_through_onnx_runtime() {
    let (largest, mean) = difference(BackboneKind::Compact, &[], 96, 128, 17);
    assert!(largest < 1e-2 && mean < 1e-3, "{largest} {mean}");
}

#[test]
fn raft_stereo_agrees_through_onnx_runtime() {
    let overrides = [
        "network.raft_stereo.hidden_dim=32",
        "network.raft_stereo.test_iters=3",
    ];
    let (largest, mean) = difference(BackboneKind::RaftStereo, &overrides, 96, 128, 17);
    assert!(largest < 1e-2 && mean < 1e-3, "{largest} {mean}");
}

#[test]
fn igev_stereo_agrees_through_onnx_runtime() {
    let overrides = [
        "network.igev.hidden_dim=32",
        "network.igev.test_iters=3",
        "network.igev.max_disp=64",
    ];
    let (largest, mean) = difference(BackboneKind::Igev, &overrides, 96, 128, 17);
    assert!(largest < 1e-2 && mean < 1e-3, "{largest} {mean}");
}
