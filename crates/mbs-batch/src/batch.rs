//! One batch on the host: random triplets and crops drawn for a step and
//! decoded into `[B, 3, H, W]` float buffers.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use mbs_core::formats::rgb::read_rgb;
use mbs_core::{FormatError, RgbImage};
use rand::Rng;

use mbs_image::planar::{Window, append_chw};

use crate::error::BatchError;
use crate::rng::{Stream, step_rng};
use crate::samples::{TrainingSamples, ViewPaths};
use crate::sampling::{Triplet, draw_triplet};

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
    /// The crop window of each item (the same in its three views).
    pub windows: Vec<Window>,
    /// Images that could not be used, each with the error (which names
    /// it); their items were drawn again.
    pub skipped: Vec<(PathBuf, String)>,
}

/// The largest batch (`data.batch_size`; the paper trains with 16).
pub const MAX_BATCH_SIZE: usize = 1024;

/// The smallest crop side a batch may have (`data.crop_height` and
/// `data.crop_width` of a training run).
pub const MIN_CROP_SIDE: usize = 16;

/// Draws of an item after which a batch gives up on unreadable images: the
/// data is then broken, not one file of it.
pub const MAX_DRAWS_PER_ITEM: usize = 8;

/// Draws and decodes the batch of `step`: for each item a sample, a triplet
/// and a crop window, all from [`step_rng`]`(seed, step, Batch)`.
pub fn load_batch(
    samples: &TrainingSamples,
    batch_size: usize,
    (height, width): (usize, usize),
    seed: u64,
    step: usize,
) -> Result<HostBatch, BatchError> {
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
        windows: Vec::with_capacity(batch_size),
        skipped: Vec::new(),
    };
    for _ in 0..batch_size {
        let mut draws = 0;
        let item = loop {
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
            draws += 1;
            match decode_item(sample, triplet) {
                Ok(views) => break (sample, triplet, window, views),
                Err(Unusable::Fatal(error)) => return Err(error),
                // A file whose header is fine and pixels are not (validate
                // --deep finds them) costs its items, not the run.
                Err(Unusable::Undecodable(path, error)) if draws < MAX_DRAWS_PER_ITEM => {
                    batch.skipped.push((path, error));
                }
                Err(Unusable::Undecodable(_, error)) => {
                    return Err(BatchError::Input(format!(
                        "{error} ({MAX_DRAWS_PER_ITEM} draws of one item in a row met unusable \
                         images; check the data with `mbs-tool validate --deep`)"
                    )));
                }
            }
        };
        let (sample, triplet, window, [reference, student, teacher]) = item;
        append_chw(&window, &reference, &mut batch.reference);
        append_chw(&window, &student, &mut batch.student_target);
        append_chw(&window, &teacher, &mut batch.teacher_target);
        batch.ratios.push(triplet.ratio(&samples.rig));
        batch.triplets.push(triplet);
        batch.sample_ids.push(sample.id.clone());
        batch.windows.push(window);
    }
    Ok(batch)
}

/// Why an item's views cannot be used.
enum Unusable {
    /// An image's content does not decode (the file, the error): the item
    /// is drawn again.
    Undecodable(PathBuf, String),
    /// The system refused a file, or an image is not the size the manifest
    /// says: not a matter of one corrupt file, so the run stops.
    Fatal(BatchError),
}

/// The reference, student and teacher views of an item, or why not.
fn decode_item(sample: &ViewPaths, triplet: Triplet) -> Result<[Arc<RgbImage>; 3], Unusable> {
    let decode = |view: usize| {
        let path = &sample.views[view];
        let image = read_rgb(path).map_err(|e| match e {
            FormatError::Io { .. } => Unusable::Fatal(e.into()),
            undecodable => Unusable::Undecodable(path.clone(), undecodable.to_string()),
        })?;
        check_size(path, &image, sample.size).map_err(Unusable::Fatal)?;
        Ok(Arc::new(image))
    };
    let reference = decode(triplet.reference)?;
    let student = decode(triplet.student)?;
    // Targets are drawn with replacement: the same view is decoded once.
    let teacher = if triplet.teacher == triplet.student {
        Arc::clone(&student)
    } else {
        decode(triplet.teacher)?
    };
    Ok([reference, student, teacher])
}

/// An error unless `image` has the size the manifest promised.
fn check_size(
    path: &Path,
    image: &RgbImage,
    (width, height): (u32, u32),
) -> Result<(), BatchError> {
    if image.dimensions() == (width, height) {
        Ok(())
    } else {
        Err(BatchError::data(
            path,
            format!(
                "the image is {}x{} but the manifest says {width}x{height}",
                image.width(),
                image.height()
            ),
        ))
    }
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
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two samples of three 32x16 views in `dir`; the views of sample 1
    /// are `corrupt` (a PNG whose pixels do not decode) when asked.
    fn samples(dir: &Path, corrupt: &[usize]) -> TrainingSamples {
        let image = RgbImage::from_fn(32, 16, |x, y| image::Rgb([x as u8 * 8, y as u8 * 16, 0]));
        let samples = (0..2)
            .map(|s| {
                let views = (0..3)
                    .map(|v| {
                        let path = dir.join(format!("s{s}_v{v}.png"));
                        image.save(&path).unwrap();
                        if s == 1 && corrupt.contains(&v) {
                            let mut bytes = std::fs::read(&path).unwrap();
                            let middle = bytes.len() / 2;
                            bytes[middle..middle + 8].fill(0xee);
                            std::fs::write(&path, bytes).unwrap();
                        }
                        path
                    })
                    .collect();
                ViewPaths {
                    id: format!("s{s}"),
                    views,
                    size: (32, 16),
                }
            })
            .collect();
        TrainingSamples {
            rig: mbs_core::Rig::centred(3, 0.1, 100.0, 32, 16),
            samples,
        }
    }

    #[test]
    fn items_meeting_an_unusable_image_are_drawn_again_within_a_bound() {
        let dir = tempfile::tempdir().unwrap();
        let clean = load_batch(&samples(dir.path(), &[]), 8, (16, 16), 5, 0).unwrap();
        assert!(clean.skipped.is_empty());
        let broken = samples(dir.path(), &[1]);
        let batch = load_batch(&broken, 8, (16, 16), 5, 0).unwrap();
        assert_eq!(batch.triplets.len(), 8);
        assert!(!batch.skipped.is_empty());
        assert!(
            batch
                .skipped
                .iter()
                .all(|(path, _)| path.ends_with("s1_v1.png"))
        );
        // Every item that met the broken view was drawn again: none uses it.
        let uses_broken = |i: usize| {
            let t = batch.triplets[i];
            batch.sample_ids[i] == "s1" && [t.reference, t.student, t.teacher].contains(&1)
        };
        assert!((0..8).all(|i| !uses_broken(i)));
        // With every image of one sample broken and the other gone, the
        // data is broken, not one file: the batch gives up, saying so.
        let mut hopeless = samples(dir.path(), &[0, 1, 2]);
        hopeless.samples.remove(0);
        let err = load_batch(&hopeless, 2, (16, 16), 5, 0)
            .unwrap_err()
            .to_string();
        assert!(err.contains("8 draws of one item in a row"), "{err}");
    }
}
