//! Moving data between the host and the device: images (or crops of them)
//! into planar `[B, 3, H, W]` tensors in `[0, 1]`, and tensors back into
//! `f32` vectors, with an error naming what was read.

use burn::tensor::{Device, Tensor, TensorData};
use mbs_core::RgbImage;
use mbs_image::planar::{Window, append_chw};

use crate::error::NetError;

/// Planar values of `shape` as a tensor on `device`.
pub fn chw_tensor(data: Vec<f32>, shape: [usize; 4], device: &Device) -> Tensor<4> {
    Tensor::from_data(TensorData::new(data, shape), device)
}

/// A whole image as a `[1, 3, H, W]` tensor in `[0, 1]` on `device`.
pub fn image_tensor(image: &RgbImage, device: &Device) -> Tensor<4> {
    let (height, width) = (image.height() as usize, image.width() as usize);
    let mut out = Vec::with_capacity(3 * width * height);
    append_chw(&Window::whole(image), image, &mut out);
    chw_tensor(out, [1, 3, height, width], device)
}

/// The first value of `tensor` as f32.
pub fn read_scalar(tensor: Tensor<1>, what: &'static str) -> Result<f32, NetError> {
    read_all(tensor, what)?
        .first()
        .copied()
        .ok_or(NetError::Readback(what))
}

/// Every value of `tensor` as f32, row-major.
pub fn read_all<const D: usize>(
    tensor: Tensor<D>,
    what: &'static str,
) -> Result<Vec<f32>, NetError> {
    tensor
        .into_data()
        .try_into_vec::<f32>()
        .map_err(|_| NetError::Readback(what))
}
