//! One batch on the host: random triplets and crops drawn for a step and
//! decoded into `[B, 3, H, W]` float buffers.

use std::ops::Range;
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
    /// Items in the step's whole batch.
    pub batch_size: usize,
    /// Which of them this batch holds: all, or one share of a
    /// data-parallel step ([`load_share`]).
    pub items: Range<usize>,
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

/// The `part`-th of `parts` consecutive shares of a batch of `items`
/// items, whose sizes differ by at most one (the first ones are the
/// larger): the items a device or a process of a data-parallel step takes.
pub fn share(items: usize, parts: usize, part: usize) -> Range<usize> {
    let parts = parts.max(1);
    let (size, larger) = (items / parts, items % parts);
    let start = part * size + part.min(larger);
    start..start + size + usize::from(part < larger)
}

/// Draws and decodes the batch of `step`: for each item a sample, a triplet
/// and a crop window, all from [`step_rng`]`(seed, step, Batch)`.
pub fn load_batch(
    samples: &TrainingSamples,
    batch_size: usize,
    crop: (usize, usize),
    seed: u64,
    step: usize,
) -> Result<HostBatch, BatchError> {
    load_share(samples, batch_size, crop, seed, step, 0..batch_size)
}

/// The items `items` of the batch of `step` ([`load_batch`]), decoding
/// only theirs: every item's first draw comes from the step's generator
/// (the items before `items` are drawn, not decoded, to reach theirs), and
/// an item whose images do not decode is drawn again from a generator of
/// its own ([`Stream::Redraw`]), so a share holds exactly the items the
/// whole batch holds there.
pub fn load_share(
    samples: &TrainingSamples,
    batch_size: usize,
    (height, width): (usize, usize),
    seed: u64,
    step: usize,
    items: Range<usize>,
) -> Result<HostBatch, BatchError> {
    if items.start > items.end || items.end > batch_size {
        return Err(BatchError::InvalidSetting {
            name: "items",
            value: format!("{items:?}"),
            reason: format!("a range of the batch's {batch_size} items"),
        });
    }
    let mut rng = step_rng(seed, step, Stream::Batch);
    let plane = 3 * height * width;
    let size = items.len();
    let mut batch = HostBatch {
        step,
        height,
        width,
        batch_size,
        items: items.clone(),
        reference: Vec::with_capacity(size * plane),
        student_target: Vec::with_capacity(size * plane),
        teacher_target: Vec::with_capacity(size * plane),
        triplets: Vec::with_capacity(size),
        ratios: Vec::with_capacity(size),
        sample_ids: Vec::with_capacity(size),
        windows: Vec::with_capacity(size),
        skipped: Vec::new(),
    };
    for item in 0..items.end {
        let first = Draw::from(samples, (height, width), &mut rng);
        if !items.contains(&item) {
            continue;
        }
        let mut redraws = step_rng(seed, step, Stream::Redraw(item));
        let (draw, views) = decode_or_redraw(
            samples,
            (height, width),
            first,
            &mut redraws,
            &mut batch.skipped,
        )?;
        batch.push_item(samples, &draw, &views);
    }
    Ok(batch)
}

/// The images of the item `first` drew, or, while they do not decode, of
/// the item drawn again from `redraws` (at most [`MAX_DRAWS_PER_ITEM`]
/// draws in all), with the draw that decoded; each image that did not
/// decode is added to `skipped`.
fn decode_or_redraw(
    samples: &TrainingSamples,
    crop: (usize, usize),
    first: Draw,
    redraws: &mut impl Rng,
    skipped: &mut Vec<(PathBuf, String)>,
) -> Result<(Draw, [Arc<RgbImage>; 3]), BatchError> {
    let mut draw = first;
    let mut draws = 1;
    loop {
        let sample = &samples.samples[draw.sample];
        match decode_item(sample, draw.triplet) {
            Ok(views) => return Ok((draw, views)),
            Err(Unusable::Fatal(error)) => return Err(error),
            // A file whose header is fine and pixels are not (validate
            // --deep finds them) costs its items, not the run.
            Err(Unusable::Undecodable(path, error)) if draws < MAX_DRAWS_PER_ITEM => {
                skipped.push((path, error));
            }
            Err(Unusable::Undecodable(_, error)) => {
                return Err(BatchError::Input(format!(
                    "{error} ({MAX_DRAWS_PER_ITEM} draws of one item in a row met unusable \
                     images; check the data with `mbs-tool validate --deep`)"
                )));
            }
        }
        draw = Draw::from(samples, crop, redraws);
        draws += 1;
    }
}

impl HostBatch {
    /// Appends one decoded item: the crops of its reference, student target
    /// and teacher target views, and what was drawn.
    fn push_item(&mut self, samples: &TrainingSamples, draw: &Draw, views: &[Arc<RgbImage>; 3]) {
        let [reference, student, teacher] = views;
        append_chw(&draw.window, reference, &mut self.reference);
        append_chw(&draw.window, student, &mut self.student_target);
        append_chw(&draw.window, teacher, &mut self.teacher_target);
        self.ratios.push(draw.triplet.ratio(&samples.rig));
        self.triplets.push(draw.triplet);
        self.sample_ids
            .push(samples.samples[draw.sample].id.clone());
        self.windows.push(draw.window);
    }
}

/// The random choices of one item: a sample, a triplet of its views and a
/// crop window.
struct Draw {
    sample: usize,
    triplet: Triplet,
    window: Window,
}

impl Draw {
    /// The next item's choices from `rng` for crops of `height x width`.
    fn from<R: Rng>(
        samples: &TrainingSamples,
        (height, width): (usize, usize),
        rng: &mut R,
    ) -> Self {
        let sample = rng.random_range(0..samples.samples.len());
        let triplet = draw_triplet(samples.rig.num_views, rng);
        let (image_width, image_height) = samples.samples[sample].size;
        let top = rng.random_range(0..=(image_height as usize).saturating_sub(height));
        let left = rng.random_range(0..=(image_width as usize).saturating_sub(width));
        Draw {
            sample,
            triplet,
            window: Window {
                top,
                left,
                height,
                width,
            },
        }
    }
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
    fn shares_are_consecutive_cover_the_batch_and_differ_by_at_most_one() {
        let shares: Vec<_> = (0..3).map(|part| share(8, 3, part)).collect();
        assert_eq!(shares, [0..3, 3..6, 6..8]);
        assert_eq!(share(4, 2, 1), 2..4);
        assert_eq!(share(1, 2, 1), 1..1);
    }

    /// A share holds exactly the items the whole batch holds there, with
    /// only its own items decoded, also when another share's items meet
    /// unusable images and are drawn again.
    #[test]
    fn a_share_decodes_only_its_items_and_they_are_the_whole_batchs() {
        let dir = tempfile::tempdir().unwrap();
        for corrupt in [&[][..], &[1]] {
            let samples = samples(dir.path(), corrupt);
            let whole = load_batch(&samples, 4, (16, 16), 7, 3).unwrap();
            let halves =
                [0..2, 2..4].map(|items| load_share(&samples, 4, (16, 16), 7, 3, items).unwrap());
            let plane = 3 * 16 * 16;
            for (half, items) in halves.iter().zip([0..2, 2..4]) {
                // Two of the step's four items decoded, pixels included,
                // and they are the whole batch's items there.
                assert_eq!((half.len(), half.reference.len()), (2, 2 * plane));
                assert_eq!(&half.triplets[..], &whole.triplets[items.clone()]);
                assert_eq!(&half.sample_ids[..], &whole.sample_ids[items.clone()]);
                assert_eq!(&half.windows[..], &whole.windows[items.clone()]);
                let pixels = items.start * plane..items.end * plane;
                assert_eq!(&half.reference[..], &whole.reference[pixels.clone()]);
                assert_eq!(&half.teacher_target[..], &whole.teacher_target[pixels]);
                assert_eq!((half.items.clone(), half.batch_size), (items, 4));
            }
        }
        let samples = samples(dir.path(), &[]);
        let err = load_share(&samples, 4, (16, 16), 7, 3, 3..5).unwrap_err();
        assert!(err.to_string().contains("4 items"), "{err}");
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
