//! Times the convolutions of RAFT-Stereo and IGEV-Stereo one layer at a
//! time on the CPU (batch 1, f32), as the networks run them
//! (`Convolve::convolve`: mbs-conv's kernels), or with `--burn` as burn's
//! `flex` backend alone runs them (`Conv2d::forward`): the forward pass
//! alone (no autodiff), forward and backward for the weight gradient only
//! (the input does not require one), and forward and backward for both
//! gradients. `tools/bench/conv_layers_vs_torch.py` runs it beside the same
//! layers in PyTorch (issue 29). Run in release:
//!
//! ```text
//! RAYON_NUM_THREADS=2 cargo run --release -p mbs-nets --example conv_layers -- [ROUNDS] [--burn]
//! ```
//!
//! Prints one JSON line per layer: `name`, `forward_ms`, `weight_grad_ms`,
//! `both_grads_ms` (medians of ROUNDS, default 5, after one warm-up).

use std::time::Instant;

use burn::nn::conv::{Conv2dConfig, Conv3dConfig};
use burn::nn::{PaddingConfig2d, PaddingConfig3d};
use burn::tensor::{Device, Distribution, Tensor};
use mbs_nets::cpu_conv::Convolve;

/// One convolution of the networks: channels, kernel side, stride, groups
/// and input size (`depth` 0 for a 2-D layer).
struct Layer {
    name: &'static str,
    channels: [usize; 2],
    kernel: usize,
    stride: usize,
    groups: usize,
    depth: usize,
    height: usize,
    width: usize,
}

/// The layers timed: the issue's four and the other shapes that dominate
/// the two networks at the paper's 384x512 crop.
const LAYERS: [Layer; 7] = [
    Layer {
        name: "7x7/2 3->64 @384x512 (RAFT encoder stem)",
        channels: [3, 64],
        kernel: 7,
        stride: 2,
        groups: 1,
        depth: 0,
        height: 384,
        width: 512,
    },
    Layer {
        name: "3x3 64->64 @192x256 (RAFT residual block)",
        channels: [64, 64],
        kernel: 3,
        stride: 1,
        groups: 1,
        depth: 0,
        height: 192,
        width: 256,
    },
    Layer {
        name: "3x3 128->128 @48x64 (RAFT update block)",
        channels: [128, 128],
        kernel: 3,
        stride: 1,
        groups: 1,
        depth: 0,
        height: 48,
        width: 64,
    },
    Layer {
        name: "1x1 128->256 @96x128 (pointwise)",
        channels: [128, 256],
        kernel: 1,
        stride: 1,
        groups: 1,
        depth: 0,
        height: 96,
        width: 128,
    },
    Layer {
        name: "depthwise 3x3 96 ch @96x128 (IGEV MobileNetV2)",
        channels: [96, 96],
        kernel: 3,
        stride: 1,
        groups: 96,
        depth: 0,
        height: 96,
        width: 128,
    },
    Layer {
        name: "depthwise 3x3/2 144 ch @96x128 (IGEV MobileNetV2)",
        channels: [144, 144],
        kernel: 3,
        stride: 2,
        groups: 144,
        depth: 0,
        height: 96,
        width: 128,
    },
    Layer {
        name: "3x3x3 16->16 @24x48x64 (IGEV cost hourglass)",
        channels: [16, 16],
        kernel: 3,
        stride: 1,
        groups: 1,
        depth: 24,
        height: 48,
        width: 64,
    },
];

/// Median of `rounds` timings (ms) of `run`, after one warm-up call.
fn median_ms(rounds: usize, mut run: impl FnMut()) -> f64 {
    run();
    let mut times: Vec<f64> = (0..rounds)
        .map(|_| {
            let start = Instant::now();
            run();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

/// The three timings of a layer: `layer` builds it on a device and
/// returns its forward pass, `input` builds its input on a device.
fn time_layer<const D: usize, F: Fn(Tensor<D>) -> Tensor<D>>(
    rounds: usize,
    input: impl Fn(&Device) -> Tensor<D>,
    layer: impl Fn(&Device) -> F,
) -> [f64; 3] {
    let plain = Device::flex();
    let autodiff = plain.clone().autodiff();
    let (forward, x) = (layer(&plain), input(&plain));
    let forward_ms = median_ms(rounds, || {
        let _ = forward(x.clone()).into_data();
    });
    let forward = layer(&autodiff);
    let grads_ms = |input_grad: bool| {
        let x = input(&autodiff);
        let x = if input_grad { x.require_grad() } else { x };
        median_ms(rounds, || {
            let grads = forward(x.clone()).sum().backward();
            drop(grads);
        })
    };
    [forward_ms, grads_ms(false), grads_ms(true)]
}

/// The timings of a 2-D `layer`, through mbs-conv or, with `burn_only`,
/// burn's own convolution.
fn time_2d(rounds: usize, layer: &Layer, burn_only: bool) -> [f64; 3] {
    let [from, to] = layer.channels;
    let (k, s, p) = (layer.kernel, layer.stride, layer.kernel / 2);
    time_layer(
        rounds,
        |device| {
            Tensor::<4>::random(
                [1, from, layer.height, layer.width],
                Distribution::Default,
                device,
            )
        },
        |device| {
            let conv = Conv2dConfig::new([from, to], [k, k])
                .with_stride([s, s])
                .with_padding(PaddingConfig2d::Explicit(p, p, p, p))
                .with_groups(layer.groups)
                .init(device);
            #[allow(clippy::disallowed_methods)] // burn's own, the baseline
            move |x| match burn_only {
                true => conv.forward(x),
                false => conv.convolve(x),
            }
        },
    )
}

/// The timings of a 3-D `layer`, through mbs-conv or, with `burn_only`,
/// burn's own convolution.
fn time_3d(rounds: usize, layer: &Layer, burn_only: bool) -> [f64; 3] {
    let [from, to] = layer.channels;
    let (k, s, p) = (layer.kernel, layer.stride, layer.kernel / 2);
    time_layer(
        rounds,
        |device| {
            Tensor::<5>::random(
                [1, from, layer.depth, layer.height, layer.width],
                Distribution::Default,
                device,
            )
        },
        |device| {
            let conv = Conv3dConfig::new([from, to], [k, k, k])
                .with_stride([s, s, s])
                .with_padding(PaddingConfig3d::Explicit(p, p, p))
                .with_groups(layer.groups)
                .init(device);
            #[allow(clippy::disallowed_methods)] // burn's own, the baseline
            move |x| match burn_only {
                true => conv.forward(x),
                false => conv.convolve(x),
            }
        },
    )
}

fn main() {
    let rounds: usize = std::env::args()
        .nth(1)
        .map(|r| r.parse().expect("ROUNDS is a number"))
        .unwrap_or(5);
    let burn_only = std::env::args().any(|a| a == "--burn");
    for layer in &LAYERS {
        let times = if layer.depth == 0 {
            time_2d(rounds, layer, burn_only)
        } else {
            time_3d(rounds, layer, burn_only)
        };
        println!(
            "{{\"name\":\"{}\",\"forward_ms\":{:.3},\"weight_grad_ms\":{:.3},\"both_grads_ms\":{:.3}}}",
            layer.name, times[0], times[1], times[2]
        );
    }
}
