//! Parity with the official implementation: the fixtures of
//! `tools/parity/raft_stereo_fixtures.py` (official code, seeded weights)
//! against this module with the same weights.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use burn::tensor::Device;
use serde_json::Value;

use super::*;
use crate::official::{StateDict, export_state_dict, load_state_dict};
use crate::seeded::seeded_tensor;
use crate::test_util::parity::{self, input, seeded_dict};
use crate::test_util::values;

fn fixture_path(name: &str) -> PathBuf {
    parity::fixture_path(&format!("raft_stereo_{name}"))
}

fn fixture(name: &str) -> (StateDict, Value, BTreeMap<String, Vec<usize>>) {
    parity::fixture(&format!("raft_stereo_{name}"))
}

fn config_of(official: &Value) -> RaftStereoConfig {
    let number = |key: &str| official[key].as_u64().expect("integer setting") as usize;
    let context_norm = match official["context_norm"].as_str() {
        Some("batch") => NormKind::Batch,
        Some("instance") => NormKind::Instance,
        Some("group") => NormKind::Group,
        _ => NormKind::None,
    };
    RaftStereoConfig::new()
        .with_hidden_dim(official["hidden_dims"][0].as_u64().expect("hidden dims") as usize)
        .with_gru_levels(number("n_gru_layers"))
        .with_corr_levels(number("corr_levels"))
        .with_corr_radius(number("corr_radius"))
        .with_n_downsample(number("n_downsample"))
        .with_context_norm(context_norm)
        .with_slow_fast_gru(official["slow_fast_gru"].as_bool().expect("flag"))
        .with_train_iters(number("iters"))
}

fn check_parity(name: &str) {
    let device = Device::flex();
    let (fixture, official, shapes) = fixture(name);
    let config = config_of(&official);
    let net = config.init(&device).expect("valid config");

    parity::assert_official_keys(&export_state_dict(&net), &shapes);

    let net = load_state_dict(net, &seeded_dict(&shapes), &fixture_path(name))
        .expect("the seeded official state dict loads");
    let left = input(&fixture, "left", &device);
    let right = input(&fixture, "right", &device);
    let predictions = net.iterate(left, right, config.train_iters);
    assert_eq!(predictions.len(), config.train_iters);
    for (i, prediction) in predictions.into_iter().enumerate() {
        parity::assert_matches(&fixture, &format!("disparity_{i}"), prediction, name);
    }
}

#[test]
fn matches_the_official_three_level_network() {
    check_parity("three_levels");
}

#[test]
fn matches_the_official_two_level_slow_fast_network() {
    check_parity("two_levels_slow_fast");
}

/// The three-level fixture network with the seeded weights.
fn seeded_network() -> (RaftStereo, RaftStereoConfig, BTreeMap<String, Vec<usize>>) {
    let (_, official, shapes) = fixture("three_levels");
    let config = config_of(&official);
    let net = config.init(&Device::flex()).expect("valid config");
    let net = load_state_dict(net, &seeded_dict(&shapes), Path::new("seeded")).expect("loads");
    (net, config, shapes)
}

#[test]
fn export_writes_the_official_keys_and_reads_back_identically() {
    let device = Device::flex();
    let (net, config, shapes) = seeded_network();
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("raft.safetensors");
    let (dict, counters) = export_state_dict(&net);
    dict.write_safetensors(&path, &counters).expect("written");

    // Every key of the official state dict, counters included, and no other.
    let bytes = std::fs::read(&path).expect("readable");
    let file = safetensors::SafeTensors::deserialize(&bytes).expect("safetensors");
    let mut names: Vec<String> = file.names().into_iter().map(str::to_owned).collect();
    names.sort();
    assert_eq!(names, shapes.keys().cloned().collect::<Vec<_>>());
    let counter = file
        .tensor("cnet.norm1.num_batches_tracked")
        .expect("batch-norm counter");
    assert_eq!(counter.dtype(), safetensors::Dtype::I64);

    let reloaded = config.init(&device).expect("valid config");
    let reloaded = load_state_dict(reloaded, &StateDict::read(&path).expect("reads"), &path)
        .expect("an export loads back");
    let (fixture, _, _) = fixture("three_levels");
    let run = |net: &RaftStereo| {
        let left = input(&fixture, "left", &device);
        let right = input(&fixture, "right", &device);
        values(net.iterate(left, right, 2).pop().expect("two iterations"))
    };
    assert_eq!(run(&net), run(&reloaded));
}

#[test]
fn reads_a_pytorch_pth_with_the_data_parallel_prefix() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/parity/raft_stereo_part.pth");
    let dict = StateDict::read(&path).expect("a .pth state dict");
    let keys: Vec<&String> = dict.tensors.keys().collect();
    assert_eq!(
        keys,
        [
            "context_zqr_convs.0.bias",
            "context_zqr_convs.0.weight",
            "context_zqr_convs.1.bias",
            "context_zqr_convs.1.weight",
            "context_zqr_convs.2.bias",
            "context_zqr_convs.2.weight",
        ]
    );
    for (key, tensor) in &dict.tensors {
        let want = seeded_tensor(key, &tensor.shape).expect("seeded");
        assert_eq!(tensor.values, want, "{key}");
    }
    // A partial state dict is refused, naming what is missing (and not the
    // keys it has).
    let (_, official, _) = fixture("three_levels");
    let net = config_of(&official).init(&Device::flex()).expect("valid");
    let message = load_state_dict(net, &dict, &path)
        .expect_err("incomplete")
        .to_string();
    assert!(message.contains("raft_stereo_part.pth"), "{message}");
    assert!(message.contains("keys missing: cnet."), "{message}");
    assert!(!message.contains("context_zqr_convs"), "{message}");
    assert!(!message.contains("unexpected"), "{message}");
}

#[test]
fn weights_of_another_configuration_are_refused_with_the_keys() {
    let (net, _, _) = seeded_network();
    let (dict, _) = export_state_dict(&net);
    let (_, official, _) = fixture("two_levels_slow_fast");
    let other = config_of(&official).init(&Device::flex()).expect("valid");
    let message = load_state_dict(other, &dict, Path::new("three.safetensors"))
        .expect_err("different widths and levels")
        .to_string();
    assert!(
        message.starts_with("weights three.safetensors: does not match"),
        "{message}"
    );
    // Hidden width 32 against 24, and batch-norm parameters for an
    // instance-normalised context encoder.
    let wrong = "keys with the wrong shape: cnet.outputs08.0.1.weight \
                 (file [32, 128, 3, 3], network [24, 128, 3, 3])";
    assert!(message.contains(wrong), "{message}");
    assert!(
        message.contains("keys unexpected: cnet.layer1.0.norm1.bias"),
        "{message}"
    );
    assert!(message.contains(" more"), "{message}");
}

#[test]
fn odd_sizes_are_padded_and_cropped_back() {
    use burn::tensor::{Distribution, Tensor};
    let device = Device::flex();
    let net = RaftStereoConfig::new()
        .with_hidden_dim(16)
        .with_gru_levels(2)
        .with_test_iters(1)
        .init(&device)
        .expect("valid");
    // KITTI-like odd sides: 4 x ceil(h / 4) would not give the input back.
    let image = || Tensor::<4>::random([1, 3, 43, 75], Distribution::Default, &device);
    let disparity = net.disparity(image(), image());
    assert_eq!(disparity.dims(), [1, 1, 43, 75]);
    assert!(values(disparity).iter().all(|d| d.is_finite()));
}

#[test]
fn narrow_images_at_one_eighth_keep_every_correlation_level() {
    use burn::tensor::{Distribution, Tensor};
    let device = Device::flex();
    let net = RaftStereoConfig::new()
        .with_hidden_dim(16)
        .with_gru_levels(2)
        .with_n_downsample(3)
        .with_test_iters(1)
        .init(&device)
        .expect("valid");
    // 96 columns are 12 at 1/8: levels of 12, 6, 3 and 1 columns (the
    // pooling after the last level used to panic); 32 columns are 4: the
    // last level would have none.
    for [height, width] in [[48, 96], [32, 32]] {
        let image = || Tensor::<4>::random([1, 3, height, width], Distribution::Default, &device);
        let disparity = net.disparity(image(), image());
        assert_eq!(disparity.dims(), [1, 1, height, width]);
        assert!(values(disparity).iter().all(|d| d.is_finite()));
    }
}
