//! One batch on the host: random triplets and crops drawn for a step,
//! decoded into `[B, 3, H, W]` float buffers, and turned into the tensors
//! of an [`StepBatch`] (with the student's augmentation) on the training
//! thread.

use std::path::Path;

use burn::tensor::{Device, Tensor, TensorData};
use mbs_core::RgbImage;
use mbs_core::formats::rgb::read_rgb;
use rand::Rng;

use super::samples::TrainingSamples;
use super::{Stream, step_rng};
use crate::augment::AugmentConfig;
use crate::error::TrainError;
use crate::sampling::{Triplet, draw_triplet};
use crate::step::StepBatch;

/// A decoded batch: clean crops of the reference and both targets.
#[derive(Debug, Clone, PartialEq)]
pub struct HostBatch {
    /// The step this batch is for.
    pub step: usize,
    /// Crop height.
    pub height: usize,
    /// Crop width.
    pub width: usize,
    /// Reference crops, `[B, 3, H, W]` row-major in `[0, 1]`.
    pub reference: Vec<f32>,
    /// Student target crops.
    pub student_target: Vec<f32>,
    /// Teacher target crops.
    pub teacher_target: Vec<f32>,
    /// The triplet of each item.
    pub triplets: Vec<Triplet>,
    /// Baseline ratio `r = B_s / B_t` of each item.
    pub ratios: Vec<f64>,
    /// The sample id of each item.
    pub sample_ids: Vec<String>,
}

/// Draws and decodes the batch of `step`: for each item a sample, a triplet
/// and a crop window, all from [`step_rng`]`(seed, step, Batch)`.
pub fn load_batch(
    samples: &TrainingSamples,
    batch_size: usize,
    (height, width): (usize, usize),
    seed: u64,
    step: usize,
) -> Result<HostBatch, TrainError> {
    let mut rng = step_rng(seed, step, Stream::Batch);
    let plane = 3 * height * width;
    let mut batch = HostBatch {
        step,
        height,
        width,
        reference: Vec::with_capacity(batch_size * plane),
        student_target: Vec::with_capacity(batch_size * plane),
        teacher_target: Vec::with_capacity(batch_size * plane),
        triplets: Vec::with_capacity(batch_size),
        ratios: Vec::with_capacity(batch_size),
        sample_ids: Vec::with_capacity(batch_size),
    };
    for _ in 0..batch_size {
        let sample = &samples.samples[rng.random_range(0..samples.samples.len())];
        let triplet = draw_triplet(samples.rig.num_views, &mut rng);
        let (image_width, image_height) = (sample.size.0 as usize, sample.size.1 as usize);
        let top = rng.random_range(0..=image_height.saturating_sub(height));
        let left = rng.random_range(0..=image_width.saturating_sub(width));
        let window = Window {
            top,
            left,
            height,
            width,
        };
        let decode = |view: usize| {
            let path = &sample.views[view];
            let image = read_rgb(path)?;
            check_size(path, &image, sample.size)?;
            Ok::<_, TrainError>(image)
        };
        window.append_chw(&decode(triplet.reference)?, &mut batch.reference);
        let student = decode(triplet.student)?;
        window.append_chw(&student, &mut batch.student_target);
        // Targets are drawn with replacement: the same view is decoded once.
        if triplet.teacher == triplet.student {
            window.append_chw(&student, &mut batch.teacher_target);
        } else {
            window.append_chw(&decode(triplet.teacher)?, &mut batch.teacher_target);
        }
        batch.ratios.push(triplet.ratio(&samples.rig));
        batch.triplets.push(triplet);
        batch.sample_ids.push(sample.id.clone());
    }
    Ok(batch)
}

/// An error unless `image` has the size the manifest promised.
fn check_size(
    path: &Path,
    image: &RgbImage,
    (width, height): (u32, u32),
) -> Result<(), TrainError> {
    if image.dimensions() == (width, height) {
        Ok(())
    } else {
        Err(TrainError::data(
            path,
            format!(
                "the image is {}x{} but the manifest says {width}x{height}",
                image.width(),
                image.height()
            ),
        ))
    }
}

/// A crop window, in pixels.
#[derive(Debug, Clone, Copy)]
struct Window {
    top: usize,
    left: usize,
    height: usize,
    width: usize,
}

impl Window {
    /// Appends the window of `image` to `out` as planar RGB in `[0, 1]`.
    fn append_chw(&self, image: &RgbImage, out: &mut Vec<f32>) {
        let stride = image.width() as usize * 3;
        let raw = image.as_raw();
        for channel in 0..3 {
            for y in self.top..self.top + self.height {
                let row = &raw[y * stride..(y + 1) * stride];
                out.extend(
                    (self.left..self.left + self.width)
                        .map(|x| row[x * 3 + channel] as f32 / 255.0),
                );
            }
        }
    }
}

/// A whole image as a `[1, 3, H, W]` tensor in `[0, 1]` on `device`.
pub fn image_tensor(image: &RgbImage, device: &Device) -> Tensor<4> {
    let (height, width) = (image.height() as usize, image.width() as usize);
    let mut out = Vec::with_capacity(3 * width * height);
    Window {
        top: 0,
        left: 0,
        height,
        width,
    }
    .append_chw(image, &mut out);
    Tensor::from_data(TensorData::new(out, [1, 3, height, width]), device)
}

impl HostBatch {
    /// Number of items.
    pub fn len(&self) -> usize {
        self.triplets.len()
    }

    /// Whether the batch has no item.
    pub fn is_empty(&self) -> bool {
        self.triplets.is_empty()
    }

    /// The tensors of one S3 step on `device`, with the student's input
    /// augmented by `augment` from [`step_rng`]`(seed, step, Augment)`.
    pub fn into_step_batch(self, device: &Device, augment: &AugmentConfig, seed: u64) -> StepBatch {
        let shape = [self.len(), 3, self.height, self.width];
        let tensor = |data: Vec<f32>| Tensor::<4>::from_data(TensorData::new(data, shape), device);
        let reference = tensor(self.reference);
        let student_target = tensor(self.student_target);
        let mut rng = step_rng(seed, self.step, Stream::Augment);
        let (augmented_reference, augmented_target) =
            augment.apply(reference.clone(), student_target.clone(), &mut rng);
        StepBatch {
            reference,
            student_target,
            teacher_target: tensor(self.teacher_target),
            augmented_reference,
            augmented_target,
            student_sides: self.triplets.iter().map(Triplet::student_side).collect(),
            teacher_sides: self.triplets.iter().map(Triplet::teacher_side).collect(),
            ratios: self.ratios,
        }
    }
}
