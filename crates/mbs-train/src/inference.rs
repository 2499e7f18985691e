//! A trained backbone on whole images: `RgbImage` pair in, disparity map
//! on the reference grid out (targets on the left go through mirroring).

use burn::tensor::{Device, Tensor, TensorData};
use mbs_core::{FloatImage, RgbImage, Side};

use crate::backbone::{Backbone, predict};
use crate::data::image_to_chw;
use crate::error::TrainError;

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
    let shape = [1, 3, height as usize, width as usize];
    let tensor = |image: &RgbImage| {
        Tensor::<4>::from_data(TensorData::new(image_to_chw(image), shape), device)
    };
    let disparity = predict(net, tensor(reference), tensor(target), &[side]);
    let values = disparity
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|_| TrainError::Readback("the disparity"))?;
    FloatImage::from_raw(width, height, values)
        .ok_or_else(|| TrainError::Shape("the network returned a map of the wrong size".into()))
}
