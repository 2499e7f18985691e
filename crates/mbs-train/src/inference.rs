//! A trained backbone on whole images: `RgbImage` pair in, disparity map
//! on the reference grid out (targets on the left go through mirroring);
//! a checkpoint's teacher as a `StereoMatcher` for `predict` and `eval`.

use std::path::Path;

use burn::tensor::Device;
use mbs_core::{FloatImage, MaskImage, RgbImage, Side};
use mbs_infer::{Disparity, InferError, StereoMatcher};

use crate::checkpoint::Checkpoint;

use crate::backbone::{Backbone, StereoNetwork, predict};
use crate::error::TrainError;
use crate::host::image_tensor;
use crate::host::read_all;

/// Disparity of `reference` (pixels, on its grid) against `target`, which
/// lies on `side` of it. The images must have the same size.
pub fn predict_image<B: Backbone>(
    net: &B,
    reference: &RgbImage,
    target: &RgbImage,
    side: Side,
    device: &Device,
) -> Result<FloatImage, TrainError> {
    if reference.dimensions() != target.dimensions() {
        return Err(TrainError::Shape(format!(
            "reference is {:?} but target is {:?} (width, height)",
            reference.dimensions(),
            target.dimensions()
        )));
    }
    let (width, height) = reference.dimensions();
    let disparity = predict(
        net,
        image_tensor(reference, device),
        image_tensor(target, device),
        &[side],
    );
    let values = read_all(disparity, "the disparity")?;
    FloatImage::from_raw(width, height, values)
        .ok_or_else(|| TrainError::Shape("the network returned a map of the wrong size".into()))
}

/// The teacher of a training checkpoint as a [`StereoMatcher`], on the
/// CPU: what `predict --checkpoint` and `eval --checkpoint` run.
pub struct TeacherMatcher {
    net: StereoNetwork,
    device: Device,
    name: String,
}

impl TeacherMatcher {
    /// Loads the teacher of a checkpoint folder, or of the newest
    /// checkpoint of a training run folder.
    pub fn open(path: &Path) -> Result<Self, TrainError> {
        let checkpoint = Checkpoint::open(path)?;
        let device = Device::flex();
        let net = checkpoint.teacher(&device)?;
        Ok(Self {
            net,
            device,
            name: format!(
                "S3 teacher ({}, step {})",
                checkpoint.dir.display(),
                checkpoint.state.steps
            ),
        })
    }
}

impl StereoMatcher for TeacherMatcher {
    fn name(&self) -> &str {
        &self.name
    }

    fn predict(&self, left: &RgbImage, right: &RgbImage) -> Result<Disparity, InferError> {
        let disparity = predict_image(&self.net, left, right, Side::Right, &self.device)
            .map_err(|e| InferError::Backend(e.to_string()))?;
        let valid =
            MaskImage::from_pixel(disparity.width(), disparity.height(), image::Luma([255]));
        Ok(Disparity { disparity, valid })
    }
}
