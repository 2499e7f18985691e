//! The student's input augmentation (paper §3.2): colour jitter of the
//! pair and random occlusion of the target (rectangles erased with the
//! target's mean colour), deterministic given the random generator.

use burn::config::Config;
use burn::tensor::{Tensor, TensorData};
use rand::Rng;

use crate::error::TrainError;
use mbs_nets::ranges;

/// Strength of each augmentation; factors are drawn uniformly from
/// `[1 - s, 1 + s]`, as torchvision's `ColorJitter`.
#[derive(Config, Debug, PartialEq)]
pub struct AugmentConfig {
    /// Brightness jitter `s`.
    #[config(default = 0.4)]
    pub brightness: f64,
    /// Contrast jitter `s` (around the image's mean grey).
    #[config(default = 0.4)]
    pub contrast: f64,
    /// Saturation jitter `s` (around each pixel's grey).
    #[config(default = 0.4)]
    pub saturation: f64,
    /// Probability that a target gets occluding rectangles.
    #[config(default = 0.5)]
    pub occlusion_probability: f64,
    /// Up to this many rectangles per occluded target (at least one).
    #[config(default = 2)]
    pub occlusion_max_rects: usize,
    /// Smallest rectangle side, pixels.
    #[config(default = 50)]
    pub occlusion_min_side: usize,
    /// Largest rectangle side, pixels.
    #[config(default = 100)]
    pub occlusion_max_side: usize,
}

impl AugmentConfig {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), TrainError> {
        for (name, value) in [
            ("brightness", self.brightness),
            ("contrast", self.contrast),
            ("saturation", self.saturation),
        ] {
            ranges::unit(name, value)?;
        }
        ranges::unit("occlusion_probability", self.occlusion_probability)?;
        ranges::require(
            self.occlusion_min_side >= 1 && self.occlusion_min_side <= self.occlusion_max_side,
            "occlusion_min_side",
            format!("{}..={}", self.occlusion_min_side, self.occlusion_max_side),
            "1 <= min side <= max side",
        )?;
        Ok(())
    }

    /// Augments a batch of pairs (`[B, 3, H, W]` in `[0, 1]`): the same
    /// colour jitter for both images of an item, then occlusion of the target.
    pub fn apply<R: Rng>(
        &self,
        reference: Tensor<4>,
        target: Tensor<4>,
        rng: &mut R,
    ) -> (Tensor<4>, Tensor<4>) {
        let [batch, _, height, width] = reference.dims();
        let device = reference.device();
        let mut draw = |s: f64| -> Vec<f32> {
            (0..batch)
                .map(|_| {
                    if s > 0.0 {
                        rng.random_range(1.0 - s..=1.0 + s) as f32
                    } else {
                        1.0
                    }
                })
                .collect()
        };
        let factors = [
            draw(self.brightness),
            draw(self.contrast),
            draw(self.saturation),
        ]
        .map(|f| {
            Tensor::<1>::from_data(TensorData::new(f, [batch]), &device).reshape([batch, 1, 1, 1])
        });
        let jitter = |images: Tensor<4>| {
            let [brightness, contrast, saturation] = factors.clone();
            let images = images * brightness;
            let mean_grey = grey(images.clone()).mean_dims(&[2, 3]);
            let images = (images - mean_grey.clone()) * contrast + mean_grey;
            let pixel_grey = grey(images.clone());
            ((images - pixel_grey.clone()) * saturation + pixel_grey).clamp(0.0, 1.0)
        };
        let (reference, target) = (jitter(reference), jitter(target));
        let mask = self.occlusion_mask(batch, height, width, rng);
        let mask =
            Tensor::<4>::from_data(TensorData::new(mask, [batch, 1, height, width]), &device);
        let mean_colour = target.clone().mean_dims(&[2, 3]);
        let target = target * (mask.clone().neg() + 1.0) + mean_colour * mask;
        (reference, target)
    }

    /// A 0/1 mask `[B, 1, H, W]` (row-major) of the rectangles to erase.
    fn occlusion_mask<R: Rng>(
        &self,
        batch: usize,
        height: usize,
        width: usize,
        rng: &mut R,
    ) -> Vec<f32> {
        let mut mask = vec![0.0f32; batch * height * width];
        for item in mask.chunks_mut(height * width) {
            if !rng.random_bool(self.occlusion_probability) {
                continue;
            }
            for _ in 0..rng.random_range(1..=self.occlusion_max_rects.max(1)) {
                let side = |rng: &mut R, limit: usize| {
                    rng.random_range(self.occlusion_min_side..=self.occlusion_max_side)
                        .min(limit)
                };
                let (h, w) = (side(rng, height), side(rng, width));
                let top = rng.random_range(0..=height - h);
                let left = rng.random_range(0..=width - w);
                for row in item[top * width..(top + h) * width].chunks_mut(width) {
                    row[left..left + w].fill(1.0);
                }
            }
        }
        mask
    }
}

/// Luma `0.299 R + 0.587 G + 0.114 B`, `[B, 1, H, W]`.
fn grey(images: Tensor<4>) -> Tensor<4> {
    let channel = |c: usize| images.clone().narrow(1, c, 1);
    channel(0) * 0.299 + channel(1) * 0.587 + channel(2) * 0.114
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::{Device, Distribution};
    use mbs_nets::test_util::{assert_close, values};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn pair(device: &Device) -> (Tensor<4>, Tensor<4>) {
        let a = Tensor::<4>::random([2, 3, 8, 10], Distribution::Uniform(0.2, 0.8), device);
        let b = Tensor::<4>::random([2, 3, 8, 10], Distribution::Uniform(0.2, 0.8), device);
        (a, b)
    }

    #[test]
    fn no_jitter_and_no_occlusion_is_the_identity() {
        let device = Device::flex();
        let (a, b) = pair(&device);
        let off = AugmentConfig::new()
            .with_brightness(0.0)
            .with_contrast(0.0)
            .with_saturation(0.0)
            .with_occlusion_probability(0.0);
        let (a2, b2) = off.apply(a.clone(), b.clone(), &mut ChaCha8Rng::seed_from_u64(1));
        assert_close(&values(a2), &values(a), 1e-6);
        assert_close(&values(b2), &values(b), 1e-6);
    }

    #[test]
    fn occlusion_fills_rectangles_with_the_mean_colour_only_in_the_target() {
        let device = Device::flex();
        let (a, b) = pair(&device);
        let config = AugmentConfig::new()
            .with_brightness(0.0)
            .with_contrast(0.0)
            .with_saturation(0.0)
            .with_occlusion_probability(1.0)
            .with_occlusion_min_side(3)
            .with_occlusion_max_side(4);
        let (a2, b2) = config.apply(a.clone(), b.clone(), &mut ChaCha8Rng::seed_from_u64(2));
        assert_close(&values(a2), &values(a), 1e-6);
        let means = values(b.clone().mean_dims(&[2, 3]));
        let (original, erased) = (values(b), values(b2));
        let plane = 8 * 10;
        let mut erased_pixels = 0;
        for (i, (o, e)) in original.iter().zip(&erased).enumerate() {
            if (o - e).abs() > 1e-7 {
                assert!(
                    (e - means[i / plane]).abs() < 1e-6,
                    "pixel {i} is neither kept nor the mean"
                );
                erased_pixels += 1;
            }
        }
        // At least one 3x3 rectangle in each of 2 items x 3 channels.
        assert!(erased_pixels >= 2 * 3 * 9, "{erased_pixels}");
    }

    #[test]
    fn deterministic_given_the_seed_and_in_range() {
        let device = Device::flex();
        let (a, b) = pair(&device);
        let config = AugmentConfig::new()
            .with_occlusion_min_side(2)
            .with_occlusion_max_side(5);
        assert!(config.validate().is_ok());
        let run = |seed| {
            let (x, y) = config.apply(a.clone(), b.clone(), &mut ChaCha8Rng::seed_from_u64(seed));
            (values(x), values(y))
        };
        assert_eq!(run(4), run(4));
        assert_ne!(run(4), run(5));
        assert!(run(4).0.iter().all(|v| (0.0..=1.0).contains(v)));
        assert!(
            AugmentConfig::new()
                .with_occlusion_min_side(0)
                .validate()
                .is_err()
        );
    }
}
