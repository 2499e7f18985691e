//! Every path (unfolded in one or several blocks, pointwise, depthwise)
//! against a direct seven-loop convolution of the definition, in value and
//! in both gradients.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;

/// The forward pass and both gradients by the definition, in f64.
fn reference(conv: &Conv, x: &[f32], w: &[f32], dy: &[f32]) -> [Vec<f32>; 3] {
    let [out_d, out_h, out_w] = conv.output();
    let [in_d, in_h, in_w] = conv.input;
    let [k_d, k_h, k_w] = conv.kernel;
    let (cin_g, cout_g) = (conv.in_per_group(), conv.out_per_group());
    let [lx, lw, ly] = conv.lengths();
    let (mut y, mut dx, mut dw) = (vec![0.0f64; ly], vec![0.0f64; lx], vec![0.0f64; lw]);
    for n in 0..conv.batch {
        for oc in 0..conv.out_channels {
            let group = oc / cout_g;
            for (od, oh, ow) in itertools(out_d, out_h, out_w) {
                let yi = (((n * conv.out_channels + oc) * out_d + od) * out_h + oh) * out_w + ow;
                for c in 0..cin_g {
                    let ic = group * cin_g + c;
                    for (a, b, e) in itertools(k_d, k_h, k_w) {
                        let at = |o: usize, k: usize, axis: usize| {
                            (o * conv.stride[axis] + k * conv.dilation[axis]) as isize
                                - conv.padding[axis][0] as isize
                        };
                        let (id, ih, iw) = (at(od, a, 0), at(oh, b, 1), at(ow, e, 2));
                        if id < 0 || ih < 0 || iw < 0 {
                            continue;
                        }
                        let (id, ih, iw) = (id as usize, ih as usize, iw as usize);
                        if id >= in_d || ih >= in_h || iw >= in_w {
                            continue;
                        }
                        let xi =
                            (((n * conv.in_channels + ic) * in_d + id) * in_h + ih) * in_w + iw;
                        let wi = (((oc * cin_g + c) * k_d + a) * k_h + b) * k_w + e;
                        y[yi] += f64::from(w[wi]) * f64::from(x[xi]);
                        dx[xi] += f64::from(w[wi]) * f64::from(dy[yi]);
                        dw[wi] += f64::from(x[xi]) * f64::from(dy[yi]);
                    }
                }
            }
        }
    }
    let narrow = |v: Vec<f64>| v.into_iter().map(|v| v as f32).collect();
    [narrow(y), narrow(dx), narrow(dw)]
}

fn itertools(a: usize, b: usize, c: usize) -> impl Iterator<Item = (usize, usize, usize)> {
    (0..a).flat_map(move |i| (0..b).flat_map(move |j| (0..c).map(move |k| (i, j, k))))
}

fn random(len: usize, rng: &mut ChaCha8Rng) -> Vec<f32> {
    (0..len).map(|_| rng.random_range(-1.0..1.0)).collect()
}

fn assert_close(what: &str, conv: &Conv, got: &[f32], want: &[f32]) {
    assert_eq!(got.len(), want.len());
    let worst = got
        .iter()
        .zip(want)
        .map(|(g, w)| (g - w).abs() / (1.0 + w.abs()))
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-5, "{what} of {conv:?}: off by {worst}");
}

/// A 2-D convolution (depth 1).
fn conv2d(
    [batch, in_channels, out_channels, groups]: [usize; 4],
    [height, width]: [usize; 2],
    kernel: usize,
    stride: usize,
    padding: [usize; 2],
    dilation: usize,
) -> Conv {
    Conv {
        batch,
        in_channels,
        out_channels,
        groups,
        input: [1, height, width],
        kernel: [1, kernel, kernel],
        stride: [1, stride, stride],
        padding: [[0, 0], padding, padding],
        dilation: [1, dilation, dilation],
    }
}

fn cases() -> Vec<Conv> {
    vec![
        conv2d([1, 3, 8, 1], [13, 17], 7, 2, [3, 3], 1), // a stem: 7x7, stride 2
        conv2d([2, 6, 5, 1], [9, 11], 3, 1, [1, 1], 1),  // 3x3, batch 2
        conv2d([1, 4, 6, 2], [8, 9], 3, 2, [1, 0], 1),   // groups, asymmetric padding
        conv2d([2, 5, 7, 1], [10, 7], 3, 1, [2, 2], 2),  // dilation
        conv2d([2, 8, 4, 1], [6, 5], 1, 1, [0, 0], 1),   // pointwise
        conv2d([1, 8, 8, 1], [6, 5], 1, 2, [0, 0], 1),   // 1x1 of stride 2
        conv2d([2, 6, 4, 2], [7, 9], 3, 1, [1, 1], 1),   // groups, stride 1 (transposed)
        conv2d([1, 3, 5, 1], [8, 7], 5, 1, [2, 1], 1),   // asymmetric padding, stride 1
        conv2d([1, 3, 5, 1], [8, 7], 3, 1, [3, 1], 1),   // padding past the reach (folded)
        conv2d([2, 6, 6, 6], [9, 10], 3, 1, [1, 1], 1),  // depthwise
        conv2d([1, 4, 8, 4], [9, 10], 3, 2, [1, 1], 1),  // depthwise x 2, stride 2
        conv2d([1, 4, 4, 4], [7, 8], 3, 1, [2, 2], 2),   // depthwise, dilated
        conv2d([2, 3, 3, 3], [11, 21], 3, 2, [1, 0], 1), // depthwise, stride 2, odd width
        conv2d([1, 2, 4, 2], [12, 19], 5, 3, [2, 1], 1), // depthwise x 2, 5x5, stride 3
        Conv {
            // IGEV-Stereo's cost-volume hourglass: 3x3x3, stride 2 in one run
            batch: 2,
            in_channels: 3,
            out_channels: 4,
            groups: 1,
            input: [5, 6, 7],
            kernel: [3, 3, 3],
            stride: [2, 1, 2],
            padding: [[1, 1], [1, 1], [1, 0]],
            dilation: [1, 1, 1],
        },
        Conv {
            batch: 1,
            in_channels: 4,
            out_channels: 4,
            groups: 4,
            input: [4, 5, 6],
            kernel: [3, 3, 3],
            stride: [1, 1, 1],
            padding: [[1, 1], [1, 1], [1, 1]],
            dilation: [1, 1, 1],
        },
    ]
}

#[test]
fn every_path_matches_the_definition_in_value_and_gradients() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for conv in cases() {
        conv.check().expect("a valid case");
        let [lx, lw, ly] = conv.lengths();
        let (x, w, dy) = (
            random(lx, &mut rng),
            random(lw, &mut rng),
            random(ly, &mut rng),
        );
        let [y, dx, dw] = reference(&conv, &x, &w, &dy);
        // The blocks of every-day use, and blocks of one output row
        // (several for every case).
        for budget in [PART_BUDGET, FOLD_BUDGET, 1] {
            assert_close("forward", &conv, &conv.forward_within(&x, &w, budget), &y);
            assert_close(
                "input gradient",
                &conv,
                &conv.input_gradient_within(&w, &dy, [budget, budget]),
                &dx,
            );
            assert_close(
                "weight gradient",
                &conv,
                &conv.weight_gradient_within(&x, &dy, budget),
                &dw,
            );
        }
    }
}

#[test]
fn bad_geometry_is_named() {
    let mut conv = conv2d([1, 3, 4, 2], [5, 5], 3, 1, [1, 1], 1);
    assert!(
        conv.check()
            .expect_err("3 channels in 2 groups")
            .contains("do not split")
    );
    conv.groups = 1;
    conv.input = [1, 1, 1];
    conv.padding = [[0, 0]; 3];
    assert!(
        conv.check()
            .expect_err("too small")
            .contains("does not fit")
    );
}
