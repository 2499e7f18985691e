//! The random draws of the student's input augmentation (paper §3.2):
//! colour jitter factors of each pair and the rectangles that occlude each
//! target. Drawing is deterministic given the generator; applying the
//! draws to images is the consumer's (the trainer's tensors, or PyTorch's).

use std::ops::Range;

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::error::BatchError;

/// Strength of each augmentation; factors are drawn uniformly from
/// `[1 - s, 1 + s]`, as torchvision's `ColorJitter`. A missing key takes
/// the paper's value.
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq)]
#[serde(default)]
pub struct AugmentConfig {
    /// Brightness jitter `s`.
    pub brightness: f64,
    /// Contrast jitter `s` (around the image's mean grey).
    pub contrast: f64,
    /// Saturation jitter `s` (around each pixel's grey).
    pub saturation: f64,
    /// Probability that a target gets occluding rectangles.
    pub occlusion_probability: f64,
    /// Up to this many rectangles per occluded target (at least one).
    pub occlusion_max_rects: usize,
    /// Smallest rectangle side, pixels.
    pub occlusion_min_side: usize,
    /// Largest rectangle side, pixels.
    pub occlusion_max_side: usize,
}

impl Default for AugmentConfig {
    /// The paper's augmentation: jitter 0.4, occlusion of half the targets
    /// by one or two rectangles of 50 to 100 pixels a side.
    fn default() -> Self {
        AugmentConfig {
            brightness: 0.4,
            contrast: 0.4,
            saturation: 0.4,
            occlusion_probability: 0.5,
            occlusion_max_rects: 2,
            occlusion_min_side: 50,
            occlusion_max_side: 100,
        }
    }
}

/// What the augmentation of one batch drew.
#[derive(Debug, Clone, PartialEq)]
pub struct AugmentDraws {
    /// Brightness factor of each item.
    pub brightness: Vec<f32>,
    /// Contrast factor of each item.
    pub contrast: Vec<f32>,
    /// Saturation factor of each item.
    pub saturation: Vec<f32>,
    /// `[B, 1, H, W]` row-major: 1 where the target is erased (filled with
    /// its mean colour), else 0.
    pub occlusion: Vec<f32>,
}

impl AugmentDraws {
    /// The draws of the items `items` of the batch they were drawn for,
    /// whose crops have `plane` (height x width) pixels.
    pub fn of_items(&self, items: Range<usize>, plane: usize) -> AugmentDraws {
        AugmentDraws {
            brightness: self.brightness[items.clone()].to_vec(),
            contrast: self.contrast[items.clone()].to_vec(),
            saturation: self.saturation[items.clone()].to_vec(),
            occlusion: self.occlusion[items.start * plane..items.end * plane].to_vec(),
        }
    }
}

impl AugmentConfig {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), BatchError> {
        for (name, value) in [
            ("brightness", self.brightness),
            ("contrast", self.contrast),
            ("saturation", self.saturation),
            ("occlusion_probability", self.occlusion_probability),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(BatchError::InvalidSetting {
                    name,
                    value: value.to_string(),
                    reason: "a number in [0, 1]".into(),
                });
            }
        }
        if self.occlusion_min_side < 1 || self.occlusion_min_side > self.occlusion_max_side {
            return Err(BatchError::InvalidSetting {
                name: "occlusion_min_side",
                value: format!("{}..={}", self.occlusion_min_side, self.occlusion_max_side),
                reason: "1 <= min side <= max side".into(),
            });
        }
        Ok(())
    }

    /// The draws for a batch of `batch` pairs of `height x width`: the
    /// brightness factors of every item, then the contrast ones, then the
    /// saturation ones, then each item's rectangles.
    pub fn draw<R: Rng>(
        &self,
        batch: usize,
        height: usize,
        width: usize,
        rng: &mut R,
    ) -> AugmentDraws {
        let mut factors = |s: f64| -> Vec<f32> {
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
        let brightness = factors(self.brightness);
        let contrast = factors(self.contrast);
        let saturation = factors(self.saturation);
        AugmentDraws {
            brightness,
            contrast,
            saturation,
            occlusion: self.occlusion_mask(batch, height, width, rng),
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn draws_are_deterministic_given_the_seed_and_in_range() {
        let config = AugmentConfig {
            occlusion_probability: 1.0,
            occlusion_min_side: 3,
            occlusion_max_side: 4,
            ..AugmentConfig::default()
        };
        assert!(config.validate().is_ok());
        let draw = |seed| config.draw(2, 8, 10, &mut ChaCha8Rng::seed_from_u64(seed));
        assert_eq!(draw(4), draw(4));
        assert_ne!(draw(4), draw(5));
        let draws = draw(4);
        for factors in [&draws.brightness, &draws.contrast, &draws.saturation] {
            assert_eq!(factors.len(), 2);
            assert!(
                factors.iter().all(|f| (0.6..=1.4).contains(f)),
                "{factors:?}"
            );
        }
        // Every item has at least one 3x3 rectangle, nothing but 0 and 1.
        for item in draws.occlusion.chunks(80) {
            assert!(item.iter().filter(|&&v| v == 1.0).count() >= 9);
            assert!(item.iter().all(|&v| v == 0.0 || v == 1.0));
        }
    }

    #[test]
    fn no_jitter_and_no_occlusion_draw_ones_and_nothing() {
        let off = AugmentConfig {
            brightness: 0.0,
            contrast: 0.0,
            saturation: 0.0,
            occlusion_probability: 0.0,
            ..AugmentConfig::default()
        };
        let draws = off.draw(3, 4, 5, &mut ChaCha8Rng::seed_from_u64(1));
        assert_eq!(draws.brightness, [1.0; 3]);
        assert_eq!(draws.saturation, [1.0; 3]);
        assert!(draws.occlusion.iter().all(|&v| v == 0.0));
    }

    #[test]
    fn out_of_range_settings_are_named() {
        let bad = AugmentConfig {
            occlusion_min_side: 0,
            ..AugmentConfig::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("occlusion_min_side")
        );
        let bad = AugmentConfig {
            contrast: 1.5,
            ..AugmentConfig::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("`contrast` = 1.5")
        );
        // Missing keys take the paper's values.
        let partial: AugmentConfig = serde_json::from_str(r#"{"brightness": 0.1}"#).unwrap();
        assert_eq!(partial.contrast, 0.4);
    }
}
