//! The networks on Vulkan (burn's wgpu backend; lavapipe in CI) against
//! the CPU: the same weights and a batch of two pairs, one of them
//! mirrored, give the same predictions and the same gradient for every
//! parameter. This runs every forward and backward kernel the networks use
//! on the GPU backend, at sizes small enough for a CPU Vulkan driver.
//!
//! Some gradients are ill-conditioned: where a leaky ReLU follows an
//! instance norm (IGEV-Stereo's `conv`), many values sit near the kink, and
//! float rounding that moves a few across it changes the gradient of every
//! parameter upstream by up to 4e-3 of its size. The CPU does the same when
//! its input images are scaled by `1 + 1e-6` or `1 - 1e-6`, so the
//! tolerance of each parameter includes that sensitivity, measured on the
//! CPU in both directions: a single ReLU whose input lies within rounding
//! of zero flips one way only (RAFT-Stereo's second residual layer on
//! Debian 12's lavapipe: one of its inputs crosses zero, which moves the
//! gradients of the stem and first block by 0.2-0.4 % of their size; the
//! CPU moves them by as much, to 1e-4, under `1 - 1e-6` and not at all
//! under `1 + 1e-6`).

use std::collections::BTreeMap;
use std::path::Path;

use burn::module::{ModuleVisitor, Param};
use burn::tensor::{Device, Gradients, Tensor, TensorData};
use mbs_core::geometry::Side;

use super::official::{OfficialLayout, export_state_dict, load_state_dict};
use super::seeded::uniforms;
use super::{Backbone, IgevStereoConfig, RaftStereoConfig, predict_sequence};
use crate::device::open_device;
use crate::test_util::parity::seeded_dict;
use crate::test_util::values;

/// Largest difference of a prediction between the devices (pixels).
const PREDICTION_TOLERANCE_PX: f32 = 1e-3;
/// Largest `|g_vulkan - g_cpu|` of a parameter, relative to `|g_cpu|`,
/// beyond twice the CPU's own change under a `1 ± 1e-6` scaling of the
/// images (the larger of the two) (measured: below 4e-6 for RAFT-Stereo, below 2e-5 for IGEV-Stereo
/// apart from the ill-conditioned parameters, whose Vulkan difference, up
/// to 3.4e-3, matches the CPU's change).
const GRADIENT_TOLERANCE: f32 = 1e-4;
/// The relative scaling of the images that measures the sensitivity.
const SENSITIVITY_SCALE: f32 = 1e-6;

/// The gradient of every float parameter, in visiting order.
struct ParameterGradients<'a> {
    grads: &'a Gradients,
    collected: Vec<Vec<f32>>,
}

impl ModuleVisitor for ParameterGradients<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let grad = param.val().grad(self.grads).map(values).unwrap_or_default();
        self.collected.push(grad);
    }
}

fn l2(values: impl Iterator<Item = f32>) -> f32 {
    values.map(|v| v * v).sum::<f32>().sqrt()
}

/// `[2, channels, 32, 64]` uniforms in `[low, high)` from the stream of `key`.
fn seeded_input(key: &str, channels: usize, low: f32, high: f32, device: &Device) -> Tensor<4> {
    let shape = [2, channels, 32, 64];
    let values = uniforms(key, shape.iter().product())
        .into_iter()
        .map(|u| low + (high - low) * u)
        .collect();
    Tensor::from_data(TensorData::new(values, shape), device)
}

/// Predictions and parameter gradients of `sum_k <prediction_k, weights>`
/// for a right-side and a left-side (mirrored) pair of seeded images,
/// multiplied by `scale`.
fn run<B: Backbone>(net: &B, device: &Device, scale: f32) -> (Vec<Vec<f32>>, Vec<Vec<f32>>) {
    let image = |key| seeded_input(key, 3, 0.0, 1.0, device) * scale;
    let predictions = predict_sequence(
        net,
        image("reference"),
        image("target"),
        &[Side::Right, Side::Left],
    );
    let weights = seeded_input("weights", 1, -1.0, 1.0, device);
    let objective = predictions
        .iter()
        .map(|prediction| (prediction.clone() * weights.clone()).sum())
        .reduce(|a, b| a + b)
        .expect("at least one prediction");
    let grads = objective.backward();
    let mut visitor = ParameterGradients {
        grads: &grads,
        collected: Vec::new(),
    };
    net.visit(&mut visitor);
    let predictions = predictions
        .into_iter()
        .map(|p| values(p.without_autodiff()))
        .collect();
    (predictions, visitor.collected)
}

/// Runs `net` with the parity fixtures' seeded weights on both devices and
/// compares (see [`GRADIENT_TOLERANCE`]).
fn assert_vulkan_matches_cpu<B: Backbone + OfficialLayout>(net: B) {
    let shapes: BTreeMap<String, Vec<usize>> = export_state_dict(&net)
        .0
        .tensors
        .into_iter()
        .map(|(key, tensor)| (key, tensor.shape))
        .collect();
    let net = load_state_dict(net, &seeded_dict(&shapes), Path::new("seeded weights"))
        .expect("the seeded weights cover every parameter");
    let cpu = Device::flex().autodiff();
    let vulkan = open_device("vulkan")
        .expect("a Vulkan driver (tools/test.sh installs Mesa's lavapipe)")
        .autodiff();
    let (cpu_predictions, cpu_grads) = run(&net.clone().fork(&cpu), &cpu, 1.0);
    let nudged_grads = [1.0 + SENSITIVITY_SCALE, 1.0 - SENSITIVITY_SCALE]
        .map(|scale| run(&net.clone().fork(&cpu), &cpu, scale).1);
    let (vulkan_predictions, vulkan_grads) = run(&net.fork(&vulkan), &vulkan, 1.0);

    for (k, (want, got)) in cpu_predictions.iter().zip(&vulkan_predictions).enumerate() {
        let worst = want
            .iter()
            .zip(got)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(
            worst <= PREDICTION_TOLERANCE_PX,
            "prediction {k} differs by up to {worst} px"
        );
    }
    assert_eq!(cpu_grads.len(), vulkan_grads.len());
    // Biases just before a normalisation have a zero gradient, computed as
    // rounding noise on both devices: compare those to the whole gradient.
    let total = l2(cpu_grads.iter().flatten().copied());
    let mut ill_conditioned = 0;
    for (i, (want, got)) in cpu_grads.iter().zip(&vulkan_grads).enumerate() {
        assert_eq!(want.len(), got.len(), "parameter {i}: gradient missing");
        let norm = l2(want.iter().copied());
        let difference = l2(want.iter().zip(got).map(|(a, b)| a - b));
        let sensitivity = nudged_grads
            .iter()
            .map(|nudged| l2(want.iter().zip(&nudged[i]).map(|(a, b)| a - b)))
            .fold(0.0, f32::max);
        let allowed = GRADIENT_TOLERANCE * norm.max(1e-3 * total);
        if sensitivity > allowed {
            ill_conditioned += 1;
        }
        assert!(
            difference <= allowed + 2.0 * sensitivity,
            "parameter {i}: gradient differs by {difference} (norm {norm}, all parameters \
             {total}; on the CPU, scaling the images by 1 ± {SENSITIVITY_SCALE} changes it by \
             up to {sensitivity})"
        );
    }
    println!(
        "{ill_conditioned} of {} parameters' gradients change beyond the tolerance when the \
         images are scaled by 1 ± {SENSITIVITY_SCALE} on the CPU",
        cpu_grads.len()
    );
}

#[test]
fn raft_stereo_on_vulkan_matches_the_cpu() {
    let net = RaftStereoConfig::new()
        .with_hidden_dim(32)
        .with_gru_levels(2)
        .with_corr_levels(2)
        .with_n_downsample(3)
        .with_train_iters(2)
        .init(&Device::flex().autodiff())
        .expect("valid config");
    assert_vulkan_matches_cpu(net);
}

#[test]
fn igev_stereo_on_vulkan_matches_the_cpu() {
    let net = IgevStereoConfig::new()
        .with_hidden_dim(16)
        .with_gru_levels(2)
        .with_max_disp(32)
        .with_train_iters(2)
        .init(&Device::flex().autodiff())
        .expect("valid config");
    assert_vulkan_matches_cpu(net);
}
