//! Moving data between the host and the device: images (or crops of them)
//! into planar `[B, 3, H, W]` tensors in `[0, 1]`, and tensors back into
//! `f32` vectors, with an error naming what was read.

use burn::tensor::{Device, Tensor, TensorData};
use mbs_core::RgbImage;

use crate::error::NetError;

/// A crop window, in pixels.
#[derive(Debug, Clone, Copy)]
pub struct Window {
    /// First row.
    pub top: usize,
    /// First column.
    pub left: usize,
    /// Rows.
    pub height: usize,
    /// Columns.
    pub width: usize,
}

/// Appends `window` of `image` to `out` as planar RGB in `[0, 1]`.
pub fn append_chw(window: &Window, image: &RgbImage, out: &mut Vec<f32>) {
    let stride = image.width() as usize * 3;
    let raw = image.as_raw();
    for channel in 0..3 {
        for y in window.top..window.top + window.height {
            let row = &raw[y * stride..(y + 1) * stride];
            out.extend(
                (window.left..window.left + window.width)
                    .map(|x| row[x * 3 + channel] as f32 / 255.0),
            );
        }
    }
}

/// Planar values of `shape` as a tensor on `device`.
pub fn chw_tensor(data: Vec<f32>, shape: [usize; 4], device: &Device) -> Tensor<4> {
    Tensor::from_data(TensorData::new(data, shape), device)
}

/// A whole image as a `[1, 3, H, W]` tensor in `[0, 1]` on `device`.
pub fn image_tensor(image: &RgbImage, device: &Device) -> Tensor<4> {
    let (height, width) = (image.height() as usize, image.width() as usize);
    let mut out = Vec::with_capacity(3 * width * height);
    let whole = Window {
        top: 0,
        left: 0,
        height,
        width,
    };
    append_chw(&whole, image, &mut out);
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
        .try_to_vec::<f32>()
        .map_err(|_| NetError::Readback(what))
}
