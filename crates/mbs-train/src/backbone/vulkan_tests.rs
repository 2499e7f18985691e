//! The networks on Vulkan (burn's wgpu backend; lavapipe in CI) against
//! the CPU: the same weights and a batch of two pairs, one of them
//! mirrored, give the same predictions and the same gradient for every
//! parameter. This runs every forward and backward kernel the networks use
//! on the GPU backend, at sizes small enough for a CPU Vulkan driver.

use burn::module::{ModuleVisitor, Param};
use burn::tensor::{Device, Distribution, Gradients, Tensor};
use mbs_core::geometry::Side;

use super::{Backbone, IgevStereoConfig, RaftStereoConfig, predict_sequence};
use crate::device::open_device;
use crate::test_util::values;

/// Largest difference of a prediction between the devices (pixels).
const PREDICTION_TOLERANCE_PX: f32 = 1e-3;
/// Largest `|g_vulkan - g_cpu|` of a parameter, relative to `|g_cpu|`
/// (measured: below 4e-6 for every parameter of both networks).
const GRADIENT_TOLERANCE: f32 = 1e-4;

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

/// Predictions and parameter gradients of `sum_k <prediction_k, weights>`
/// for a right-side and a left-side (mirrored) pair of random images.
fn run<B: Backbone>(net: &B, device: &Device) -> (Vec<Vec<f32>>, Vec<Vec<f32>>) {
    let cpu = Device::flex();
    cpu.seed(5);
    let shape = [2, 3, 32, 64];
    let reference = Tensor::<4>::random(shape, Distribution::Uniform(0.0, 1.0), &cpu);
    let target = Tensor::<4>::random(shape, Distribution::Uniform(0.0, 1.0), &cpu);
    let weights = Tensor::<4>::random([2, 1, 32, 64], Distribution::Uniform(-1.0, 1.0), &cpu);
    let on_device = |tensor: Tensor<4>| Tensor::<4>::from_data(tensor.into_data(), device);
    let predictions = predict_sequence(
        net,
        on_device(reference),
        on_device(target),
        &[Side::Right, Side::Left],
    );
    let weights = on_device(weights);
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

/// Runs `net` (weights drawn on the CPU) on both devices and compares.
fn assert_vulkan_matches_cpu<B: Backbone>(net: B) {
    let cpu = Device::flex().autodiff();
    let vulkan = open_device("vulkan")
        .expect("a Vulkan driver (tools/test.sh installs Mesa's lavapipe)")
        .autodiff();
    let (cpu_predictions, cpu_grads) = run(&net.clone().fork(&cpu), &cpu);
    let (vulkan_predictions, vulkan_grads) = run(&net.fork(&vulkan), &vulkan);

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
    for (i, (want, got)) in cpu_grads.iter().zip(&vulkan_grads).enumerate() {
        assert_eq!(want.len(), got.len(), "parameter {i}: gradient missing");
        let norm = l2(want.iter().copied());
        let difference = l2(want.iter().zip(got).map(|(a, b)| a - b));
        assert!(
            difference <= GRADIENT_TOLERANCE * norm.max(1e-3 * total),
            "parameter {i}: gradient differs by {difference} (norm {norm}, all parameters {total})"
        );
    }
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
