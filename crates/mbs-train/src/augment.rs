//! The student's input augmentation (paper §3.2) applied to a batch's
//! tensors: colour jitter of each pair and occlusion of the target
//! (rectangles erased with the target's mean colour), as drawn by
//! [`AugmentConfig::draw`] (host batches, `mbs-batch`).

use burn::tensor::{Tensor, TensorData};
use rand::Rng;

pub use mbs_batch::augment::{AugmentConfig, AugmentDraws};

/// Augments a batch of pairs (`[B, 3, H, W]` in `[0, 1]`) with `draws`:
/// the same colour jitter for both images of an item (brightness, then
/// contrast around the image's mean grey, then saturation around each
/// pixel's grey, clamped to `[0, 1]`), then the target's rectangles filled
/// with its mean colour.
pub fn apply(
    draws: &AugmentDraws,
    reference: Tensor<4>,
    target: Tensor<4>,
) -> (Tensor<4>, Tensor<4>) {
    let [batch, _, height, width] = reference.dims();
    let device = reference.device();
    let factors = [&draws.brightness, &draws.contrast, &draws.saturation].map(|f| {
        Tensor::<1>::from_data(TensorData::new(f.clone(), [batch]), &device)
            .reshape([batch, 1, 1, 1])
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
    let mask = Tensor::<4>::from_data(
        TensorData::new(draws.occlusion.clone(), [batch, 1, height, width]),
        &device,
    );
    let mean_colour = target.clone().mean_dims(&[2, 3]);
    let target = target * (mask.clone().neg() + 1.0) + mean_colour * mask;
    (reference, target)
}

/// Draws `config`'s augmentation for the pairs `[B, 3, H, W]` from `rng`
/// ([`AugmentConfig::draw`]) and applies it ([`apply`]).
pub fn augment<R: Rng>(
    config: &AugmentConfig,
    reference: Tensor<4>,
    target: Tensor<4>,
    rng: &mut R,
) -> (Tensor<4>, Tensor<4>) {
    let [batch, _, height, width] = reference.dims();
    apply(&config.draw(batch, height, width, rng), reference, target)
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
        let off = AugmentConfig {
            brightness: 0.0,
            contrast: 0.0,
            saturation: 0.0,
            occlusion_probability: 0.0,
            ..AugmentConfig::default()
        };
        let (a2, b2) = augment(
            &off,
            a.clone(),
            b.clone(),
            &mut ChaCha8Rng::seed_from_u64(1),
        );
        assert_close(&values(a2), &values(a), 1e-6);
        assert_close(&values(b2), &values(b), 1e-6);
    }

    #[test]
    fn occlusion_fills_rectangles_with_the_mean_colour_only_in_the_target() {
        let device = Device::flex();
        let (a, b) = pair(&device);
        let config = AugmentConfig {
            brightness: 0.0,
            contrast: 0.0,
            saturation: 0.0,
            occlusion_probability: 1.0,
            occlusion_min_side: 3,
            occlusion_max_side: 4,
            ..AugmentConfig::default()
        };
        let (a2, b2) = augment(
            &config,
            a.clone(),
            b.clone(),
            &mut ChaCha8Rng::seed_from_u64(2),
        );
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
        let config = AugmentConfig {
            occlusion_min_side: 2,
            occlusion_max_side: 5,
            ..AugmentConfig::default()
        };
        let run = |seed| {
            let (x, y) = augment(
                &config,
                a.clone(),
                b.clone(),
                &mut ChaCha8Rng::seed_from_u64(seed),
            );
            (values(x), values(y))
        };
        assert_eq!(run(4), run(4));
        assert_ne!(run(4), run(5));
        assert!(run(4).0.iter().all(|v| (0.0..=1.0).contains(v)));
    }
}
