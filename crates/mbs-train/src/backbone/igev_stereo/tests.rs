//! Parity with the official implementation: the fixtures of
//! `tools/parity/igev_stereo_fixtures.py` (official code, seeded weights)
//! against this module with the same weights.

use burn::tensor::Device;
use serde_json::Value;

use super::*;
use crate::backbone::official::{export_state_dict, load_state_dict};
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

#[test]
fn one_s3_step_updates_every_part_and_pads_odd_sizes() {
    use crate::data::StepBatch;
    use crate::losses::LossConfig;
    use crate::schedule::OneCycleConfig;
    use crate::step::{S3Trainer, TrainerConfig};
    use burn::tensor::Distribution;
    use mbs_core::geometry::Side;

    let device = Device::flex();
    let train_device = device.clone().autodiff();
    let config = IgevStereoConfig::new()
        .with_hidden_dim(16)
        .with_gru_levels(2)
        .with_max_disp(32)
        .with_train_iters(2)
        .with_test_iters(2);
    let net = config.init(&train_device).expect("valid");
    let before = export_state_dict(&net).0;
    let trainer_config = TrainerConfig::new(LossConfig::new(), OneCycleConfig::new(1e-3, 4));
    let mut trainer = S3Trainer::new(net, &trainer_config).expect("valid");
    // 40x70: not multiples of 32, so the padding and the crop run too.
    let image = || Tensor::<4>::random([1, 3, 40, 70], Distribution::Default, &device);
    let (reference, target) = (image(), image());
    let batch = StepBatch {
        augmented_reference: reference.clone(),
        augmented_target: target.clone(),
        reference,
        student_target: target.clone(),
        teacher_target: target,
        student_sides: vec![Side::Left],
        teacher_sides: vec![Side::Right],
        ratios: vec![0.5],
    };
    let report = trainer.step(batch).expect("a step");
    assert!(
        report.loss.is_finite() && report.grad_norm > 0.0,
        "{report:?}"
    );
    let after = export_state_dict(trainer.student()).0;
    // Every trained part moved: the MobileNetV2 stem, the 3-D hourglass,
    // the context encoder, the GRU and both upsampling heads.
    for key in [
        "feature.conv_stem.weight",
        "cost_agg.conv1.0.conv.weight",
        "classifier.weight",
        "cnet.conv1.weight",
        "update_block.gru04.convz.weight",
        "spx.0.weight",
        "spx_gru.0.weight",
    ] {
        assert_ne!(
            before.tensors[key], after.tensors[key],
            "{key} did not change"
        );
    }
}
