//! A trained backbone on whole images: `RgbImage` pair in, disparity map
//! on the reference grid out (targets on the left go through mirroring).

use burn::tensor::Device;
use mbs_core::{FloatImage, RgbImage, Side};

use crate::backbone::{Backbone, predict};
use crate::data::image_tensor;
use crate::error::TrainError;
use crate::readback::read_all;

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
