//! IGEV-Stereo's volumes (the official `submodule.py` and `geometry.py`):
//! the group-wise correlation volume, the soft-argmin of the initial
//! disparity, the combined geometry encoding volume looked up around the
//! current disparity, and the context upsampling of a 1/4-resolution map.

use burn::tensor::Tensor;
use burn::tensor::activation::softmax;
use burn::tensor::ops::PadMode;

use crate::layers::counting;
use crate::raft_stereo::correlation::{lookup_offsets, sample_linear};

/// Group-wise correlation `[B, groups, D, H, W]` of left and right
/// features (`[B, C, H, W]`): for each candidate `d`, the mean over each
/// channel group of `L(x) R(x - d)`, zero where `x - d` leaves the image.
pub fn group_correlation_volume(
    left: Tensor<4>,
    right: Tensor<4>,
    candidates: usize,
    groups: usize,
) -> Tensor<5> {
    let [b, c, h, w] = left.dims();
    let planes = (0..candidates.min(w))
        .map(|d| {
            let product = left.clone().narrow(3, d, w - d) * right.clone().narrow(3, 0, w - d);
            product
                .reshape([b, groups, c / groups, h, w - d])
                .mean_dim(2)
                .reshape([b * groups, h, w - d])
                .pad((d, 0, 0, 0), PadMode::Constant(0.0))
                .reshape([b, groups, 1, h, w])
        })
        .collect();
    Tensor::cat(planes, 2)
}

/// Soft-argmin over the candidates of `[B, D, H, W]` logits: `[B, 1, H, W]`.
pub fn regress_disparity(logits: Tensor<4>) -> Tensor<4> {
    let [_, candidates, _, _] = logits.dims();
    let values = counting(candidates, &logits).reshape([1, candidates, 1, 1]);
    (softmax(logits, 1) * values).sum_dim(1)
}

/// The official `context_upsample`: each pixel of the 4x finer map is the
/// combination, by `weights` (`[B, 9, 4H, 4W]`, summing to 1), of the 3x3
/// neighbourhood (zero outside) of its coarse pixel in `map` (`[B, 1, H, W]`).
pub fn context_upsample(map: Tensor<4>, weights: Tensor<4>) -> Tensor<4> {
    let [b, _, h, w] = map.dims();
    let padded = map.pad((1, 1, 1, 1), PadMode::Constant(0.0));
    let taps = (0..3)
        .flat_map(|dy| (0..3).map(move |dx| (dy, dx)))
        .map(|(dy, dx)| padded.clone().narrow(2, dy, h).narrow(3, dx, w))
        .collect();
    let neighbours: Tensor<4> = Tensor::cat(taps, 1);
    let nearest = neighbours
        .reshape([b, 9, h, 1, w, 1])
        .expand([b, 9, h, 4, w, 4])
        .reshape([b, 9, 4 * h, 4 * w]);
    (nearest * weights).sum_dim(1)
}

/// The official `Combined_Geo_Encoding_Volume`: pyramids (pooled by 2 along
/// the disparity axis) of the geometry encoding volume and of the all-pairs
/// correlation of the matching features, looked up around the current
/// disparity.
pub struct GeoEncoding {
    /// Per level: `[B * H * W * C, D / 2^level]`.
    volume: Vec<Tensor<2>>,
    /// Per level: `[B * H * W, W / 2^level]`.
    correlation: Vec<Tensor<2>>,
    channels: usize,
    radius: usize,
    shape: [usize; 3],
}

/// Halves the columns of `rows` by averaging pairs (dropping an odd last one).
fn pool_columns(rows: &Tensor<2>) -> Tensor<2> {
    let [n, columns] = rows.dims();
    rows.clone()
        .narrow(1, 0, columns / 2 * 2)
        .reshape([n, columns / 2, 2])
        .mean_dim(2)
        .reshape([n, columns / 2])
}

fn pyramid(rows: Tensor<2>, levels: usize) -> Vec<Tensor<2>> {
    let mut out = vec![rows];
    for _ in 1..levels {
        let next = pool_columns(out.last().expect("one level at least"));
        out.push(next);
    }
    out
}

impl GeoEncoding {
    /// The pyramids of the geometry volume (`[B, C, D, H, W]`) and of the
    /// matching features (`[B, F, H, W]`).
    pub fn new(
        left: Tensor<4>,
        right: Tensor<4>,
        volume: Tensor<5>,
        levels: usize,
        radius: usize,
    ) -> Self {
        let [b, c, d, h, w] = volume.dims();
        let volume = volume.permute([0, 3, 4, 1, 2]).reshape([b * h * w * c, d]);
        let right_width = right.dims()[3];
        let correlation = left
            .permute([0, 2, 3, 1])
            .matmul(right.permute([0, 2, 1, 3]))
            .reshape([b * h * w, right_width]);
        GeoEncoding {
            volume: pyramid(volume, levels),
            correlation: pyramid(correlation, levels),
            channels: c,
            radius,
            shape: [b, h, w],
        }
    }

    /// Channels of a lookup: `levels (2 radius + 1) (C + 1)`.
    pub fn channels(levels: usize, radius: usize, volume_channels: usize) -> usize {
        levels * (2 * radius + 1) * (volume_channels + 1)
    }

    /// The lookup `[B, channels, H, W]` at the disparity `[B, 1, H, W]`
    /// (detached): per level the volume around `d` and the correlation
    /// around the matching column `x - d`.
    pub fn lookup(&self, disparity: Tensor<4>) -> Tensor<4> {
        let [b, h, w] = self.shape;
        let c = self.channels;
        let points = 2 * self.radius + 1;
        let offsets = lookup_offsets(self.radius, &disparity);
        let disparity = disparity.detach().reshape([b * h * w, 1]);
        let columns = counting(w, &disparity)
            .reshape([1, 1, w])
            .expand([b, h, w])
            .reshape([b * h * w, 1]);
        let mut parts = Vec::with_capacity(2 * self.volume.len());
        for (level, (volume, correlation)) in self.volume.iter().zip(&self.correlation).enumerate()
        {
            let scale = 2f64.powi(level as i32);
            let at = disparity.clone() / scale + offsets.clone();
            let at_every_channel = at
                .reshape([b * h * w, 1, points])
                .expand([b * h * w, c, points])
                .reshape([b * h * w * c, points]);
            parts.push(sample_linear(volume, at_every_channel).reshape([b, h, w, c * points]));
            let matching = columns.clone() / scale - disparity.clone() / scale + offsets.clone();
            parts.push(sample_linear(correlation, matching).reshape([b, h, w, points]));
        }
        Tensor::cat(parts, 3).permute([0, 3, 1, 2])
    }
}
