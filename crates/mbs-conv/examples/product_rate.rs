//! The throughput of the matrix products mbs-conv's forward pass runs on
//! the 3x3 layers still slowest against PyTorch, each product alone (a
//! pointwise convolution of `K` input channels over the block's `P`
//! positions is the product `W[C_out, K] x U[K, P]` of one unfolded
//! block) and each whole layer. Called by `tools/bench/products_vs_torch.py`,
//! which times the same products with `torch.mm` and the layers with
//! `torch.nn.Conv2d`; run with `RAYON_NUM_THREADS=1` for one core:
//!
//! ```text
//! RAYON_NUM_THREADS=1 cargo run --release -p mbs-conv --example product_rate -- 15
//! ```
//!
//! Prints one JSON line per case: its name, milliseconds (median of the
//! rounds after one warm-up) and GFLOP/s.

use std::time::Instant;

use mbs_conv::Conv;

/// A 2-D convolution of batch 1, one group, stride 1 and dilation 1.
fn conv2d(channels: [usize; 2], size: [usize; 2], kernel: usize) -> Conv {
    Conv {
        batch: 1,
        in_channels: channels[0],
        out_channels: channels[1],
        groups: 1,
        input: [1, size[0], size[1]],
        kernel: [1, kernel, kernel],
        stride: [1; 3],
        padding: [[0, 0], [kernel / 2; 2], [kernel / 2; 2]],
        dilation: [1; 3],
    }
}

/// Median milliseconds of `rounds` forward passes after one warm-up.
fn forward_ms(conv: &Conv, rounds: usize) -> f64 {
    let [input, weight, _] = conv.lengths();
    let x: Vec<f32> = (0..input).map(|i| (i % 13) as f32 * 0.01).collect();
    let w: Vec<f32> = (0..weight).map(|i| (i % 7) as f32 * 0.01).collect();
    std::hint::black_box(conv.forward(&x, &w));
    let mut times: Vec<f64> = (0..rounds)
        .map(|_| {
            let start = Instant::now();
            std::hint::black_box(conv.forward(&x, &w));
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

fn main() {
    let rounds = std::env::args()
        .nth(1)
        .and_then(|r| r.parse().ok())
        .unwrap_or(15);
    let layers = [
        ("3x3 64->64 @192x256", conv2d([64, 64], [192, 256], 3)),
        ("3x3 128->128 @48x64", conv2d([128, 128], [48, 64], 3)),
    ];
    for (name, layer) in layers {
        let taps: usize = layer.kernel.iter().product();
        let k = layer.in_channels * taps;
        // The block's positions: whole output rows within PART_BUDGET.
        let width = layer.input[2];
        let rows = (mbs_conv::PART_BUDGET / (k * width)).max(1);
        let product = conv2d([k, layer.out_channels], [rows, width], 1);
        let cases = [
            (format!("product of one block of {name}"), product),
            (format!("layer {name}"), layer),
        ];
        for (case, conv) in cases {
            let ms = forward_ms(&conv, rounds);
            let [_, weight, output] = conv.lengths();
            let flops = 2.0 * (weight * output / conv.out_channels) as f64;
            let gflops = flops / ms / 1e6;
            println!("{{\"name\":\"{case}\",\"ms\":{ms:.3},\"gflops\":{gflops:.1}}}");
        }
    }
}
