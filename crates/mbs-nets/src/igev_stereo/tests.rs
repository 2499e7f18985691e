//! Parity with the official implementation: the fixtures of
//! `tools/parity/igev_stereo_fixtures.py` (official code, seeded weights)
//! against this module with the same weights.

use burn::tensor::Device;
use serde_json::Value;

use super::*;
use crate::official::{export_state_dict, load_state_dict};
use crate::test_util::parity::{self, input, seeded_dict};

fn config_of(official: &Value) -> IgevStereoConfig {
    let number = |key: &str| official[key].as_u64().expect("integer setting") as usize;
    IgevStereoConfig::new()
        .with_hidden_dim(official["hidden_dims"][0].as_u64().expect("hidden dims") as usize)
        .with_gru_levels(number("n_gru_layers"))
        .with_corr_levels(number("corr_levels"))
        .with_corr_radius(number("corr_radius"))
        .with_max_disp(number("max_disp"))
        .with_train_iters(number("iters"))
}

fn check_parity(name: &str) {
    let stem = format!("igev_stereo_{name}");
    let device = Device::flex();
    let (fixture, official, shapes) = parity::fixture(&stem);
    let config = config_of(&official);
    let net = config.init(&device).expect("valid config");
    parity::assert_official_keys(&export_state_dict(&net), &shapes);
    let net = load_state_dict(net, &seeded_dict(&shapes), &parity::fixture_path(&stem))
        .expect("the seeded official state dict loads");
    let left = input(&fixture, "left", &device);
    let right = input(&fixture, "right", &device);
    let out = net.iterate(left, right, config.train_iters, true);
    parity::assert_matches(
        &fixture,
        "disparity_init",
        out.initial.expect("asked for"),
        name,
    );
    assert_eq!(out.iterations.len(), config.train_iters);
    for (i, prediction) in out.iterations.into_iter().enumerate() {
        parity::assert_matches(&fixture, &format!("disparity_{i}"), prediction, name);
    }
}

#[test]
fn matches_the_official_three_level_network() {
    check_parity("three_levels");
}

#[test]
fn matches_the_official_two_level_network() {
    check_parity("two_levels");
}
