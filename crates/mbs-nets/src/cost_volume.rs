//! A compact cost-volume stereo network that learns on CPU at small sizes:
//! shared features at 1/4 resolution, a correlation volume of
//! `max_disparity / 4` candidates, 2-D convolutions over it plus the raw
//! correlation as candidate logits, soft-argmin and bilinear upsampling
//! (two matrix products) to full resolution.

use crate::cpu_conv::Convolve;
use burn::config::Config;
use burn::module::Module;
use burn::nn::PaddingConfig2d;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::tensor::activation::{relu, softmax};
use burn::tensor::ops::PadMode;
use burn::tensor::{Device, FloatDType, Tensor};

use super::Backbone;
use super::layers::counting;
use super::upsample::upsample_bilinear;
use crate::error::NetError;
use crate::ranges;

/// Hyper-parameters of [`CostVolumeNet`] (its disparity range is the
/// run's `network.max_disparity`).
#[derive(Config, Debug, PartialEq)]
pub struct CostVolumeNetConfig {
    /// Channels of the 1/4-resolution features.
    #[config(default = 16)]
    pub features: usize,
    /// Channels of the cost aggregation layers.
    #[config(default = 32)]
    pub hidden: usize,
    /// Weight of the raw correlation added to the candidate logits, so an
    /// untrained network already prefers the best-matching candidate.
    #[config(default = 10.0)]
    pub correlation_weight: f64,
}

impl CostVolumeNetConfig {
    /// Checks the disparity range `max_disparity` (full-resolution pixels)
    /// and the layer widths.
    pub fn validate(&self, max_disparity: usize) -> Result<(), NetError> {
        ranges::require(
            max_disparity >= 4
                && max_disparity.is_multiple_of(4)
                && max_disparity <= ranges::MAX_DISPARITY,
            "max_disparity",
            max_disparity,
            format!("a multiple of 4 from 4 to {}", ranges::MAX_DISPARITY),
        )?;
        let channels = (2, ranges::CHANNELS.1);
        ranges::integers_in(&[
            ("features", self.features, channels),
            ("hidden", self.hidden, channels),
        ])
    }

    /// Builds the network for disparities up to `max_disparity` (a multiple
    /// of 4) with fresh weights on `device`.
    pub fn init(&self, max_disparity: usize, device: &Device) -> Result<CostVolumeNet, NetError> {
        self.validate(max_disparity)?;
        let conv = |from: usize, to: usize, stride: usize| {
            Conv2dConfig::new([from, to], [3, 3])
                .with_stride([stride, stride])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .init(device)
        };
        let candidates = max_disparity / 4;
        let (features, hidden) = (self.features, self.hidden);
        Ok(CostVolumeNet {
            stem: conv(3, features / 2, 2),
            down: conv(features / 2, features, 2),
            refine: conv(features, features, 1),
            aggregate_in: conv(candidates + features, hidden, 1),
            aggregate_mid: conv(hidden, hidden, 1),
            logits: conv(hidden, candidates, 1),
            candidates,
            correlation_weight: self.correlation_weight,
        })
    }
}

/// The compact cost-volume network (see the module documentation).
#[derive(Module, Debug)]
pub struct CostVolumeNet {
    stem: Conv2d,
    down: Conv2d,
    refine: Conv2d,
    aggregate_in: Conv2d,
    aggregate_mid: Conv2d,
    logits: Conv2d,
    candidates: usize,
    correlation_weight: f64,
}

impl CostVolumeNet {
    /// Features at 1/4 resolution of images in `[0, 1]`.
    fn features(&self, images: Tensor<4>) -> Tensor<4> {
        let x = relu(self.stem.convolve(images * 2.0 - 1.0));
        let x = relu(self.down.convolve(x));
        self.refine.convolve(x)
    }

    /// Correlation volume `[B, candidates, h, w]`: cosine similarity of
    /// `L(x)` and `R(x - d)` after removing each channel's image mean (so
    /// constant responses, such as biases, do not match everywhere); zero
    /// where `x - d` leaves the image.
    fn correlation(&self, left: Tensor<4>, right: Tensor<4>) -> Tensor<4> {
        let width = left.dims()[3];
        let unit = |features: Tensor<4>| {
            // In f16 the squares of features near their mean underflow to
            // 0 (below 6e-8) while the features do not, and dividing by
            // the 1e-6 guard alone gives "unit" vectors of length 100 and
            // more, whose products overflow the logits. The norm is taken
            // in f32 (a no-op for f32 networks).
            let dtype = features.dtype();
            let centred = (features.clone() - features.mean_dims(&[2, 3])).cast(FloatDType::F32);
            let norm = (centred.clone() * centred.clone()).sum_dim(1).sqrt() + 1e-6;
            (centred / norm).cast(dtype)
        };
        let (left, right) = (unit(left), unit(right));
        let shift = self.candidates - 1;
        let padded = right.pad((shift, 0, 0, 0), PadMode::Constant(0.0));
        let slices = (0..self.candidates)
            .map(|d| (left.clone() * padded.clone().narrow(3, shift - d, width)).sum_dim(1))
            .collect();
        Tensor::cat(slices, 1)
    }
}

impl Backbone for CostVolumeNet {
    fn disparity(&self, reference: Tensor<4>, target: Tensor<4>) -> Tensor<4> {
        let [batch, _, height, width] = reference.dims();
        let features = self.features(Tensor::cat(vec![reference, target], 0));
        let left = features.clone().narrow(0, 0, batch);
        let right = features.narrow(0, batch, batch);
        let volume = self.correlation(left.clone(), right);
        let x = relu(
            self.aggregate_in
                .convolve(Tensor::cat(vec![volume.clone(), left], 1)),
        );
        let x = relu(self.aggregate_mid.convolve(x));
        let logits = self.logits.convolve(x) + volume * self.correlation_weight;
        let probabilities = softmax(logits, 1);
        let candidates =
            counting(self.candidates, &probabilities).reshape([1, self.candidates, 1, 1]);
        // Soft-argmin at 1/4 resolution, in full-resolution pixels.
        let quarter = (probabilities * candidates).sum_dim(1) * 4.0;
        upsample_bilinear(quarter, height, width)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::values;
    use burn::tensor::Distribution;
    use std::time::Instant;

    #[test]
    fn forward_backward_gives_finite_gradients() {
        let device = Device::flex().autodiff();
        let net = CostVolumeNetConfig::new()
            .init(32, &device)
            .expect("valid config");
        let (batch, height, width) = (2, 64, 128);
        let reference =
            Tensor::<4>::random([batch, 3, height, width], Distribution::Default, &device);
        let target = Tensor::<4>::random([batch, 3, height, width], Distribution::Default, &device);
        let start = Instant::now();
        let disparity = net.disparity(reference, target);
        assert_eq!(disparity.dims(), [batch, 1, height, width]);
        let out = values(disparity.clone().inner());
        // 8 candidates at 1/4 resolution: soft-argmin lies in [0, 7 * 4].
        assert!(
            out.iter()
                .all(|d| d.is_finite() && (0.0..=28.001).contains(d))
        );
        let grads = disparity.mean().backward();
        let elapsed = start.elapsed();
        for (name, grad) in [
            ("stem", net.stem.weight.val().grad(&grads)),
            ("logits", net.logits.weight.val().grad(&grads)),
        ] {
            let grad = values(grad.expect("parameter is trained"));
            assert!(grad.iter().all(|g| g.is_finite()), "{name}");
            assert!(
                grad.iter().any(|g| *g != 0.0),
                "{name} gradient is all zero"
            );
        }
        println!(
            "CostVolumeNet forward+backward, batch {batch}, crop {height}x{width}, 32 px: {:.0} ms",
            elapsed.as_secs_f64() * 1e3
        );
    }

    #[test]
    fn rejects_a_disparity_range_not_divisible_by_four() {
        let device = Device::flex();
        assert!(CostVolumeNetConfig::new().init(30, &device).is_err());
    }

    /// Features within 1e-4 of their mean: their squares underflow in f16,
    /// and the correlation must still be a cosine (at most 1 in size) and
    /// agree with the f32 one.
    #[test]
    fn f16_correlation_of_features_near_their_mean_is_a_cosine() {
        let device = Device::flex();
        let net = CostVolumeNetConfig::new()
            .with_features(4)
            .init(32, &device)
            .expect("valid config");
        let features = |phase: usize| {
            let data: Vec<f32> = (0..4 * 2 * 16)
                .map(|i| 1e-4 * (((i * 7 + phase) % 5) as f32 - 2.0))
                .collect();
            Tensor::<4>::from_data(burn::tensor::TensorData::new(data, [1, 4, 2, 16]), &device)
        };
        let f32_volume = values(net.correlation(features(0), features(3)));
        let f16_volume = values(
            net.correlation(
                features(0).cast(FloatDType::F16),
                features(3).cast(FloatDType::F16),
            )
            .cast(FloatDType::F32),
        );
        assert!(f32_volume.iter().all(|v| v.abs() <= 1.0 + 1e-5));
        for (a, b) in f32_volume.iter().zip(&f16_volume) {
            assert!((a - b).abs() < 2e-2, "f16 {b} against f32 {a}");
        }
    }
}
