//! Small building blocks shared by the official networks.

use burn::nn::PaddingConfig2d;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::tensor::ops::PadMode;
use burn::tensor::{Device, FloatDType, Int, Tensor};

/// A square `kernel` x `kernel` convolution with bias, as PyTorch's
/// `nn.Conv2d(from, to, kernel, stride, padding)`.
pub fn conv(
    from: usize,
    to: usize,
    kernel: usize,
    stride: usize,
    padding: usize,
    device: &Device,
) -> Conv2d {
    Conv2dConfig::new([from, to], [kernel, kernel])
        .with_stride([stride, stride])
        .with_padding(PaddingConfig2d::Explicit(
            padding, padding, padding, padding,
        ))
        .init(device)
}

/// Pads a pair (`[B, C, H, W]`) by replicating its borders so that both
/// sides are multiples of `multiple`, split evenly between the two ends as
/// the official `InputPadder`; returns the padded pair and the crop that
/// takes a map of the padded size back to the original one.
pub fn pad_to_multiple(
    reference: Tensor<4>,
    target: Tensor<4>,
    multiple: usize,
) -> (Tensor<4>, Tensor<4>, impl Fn(Tensor<4>) -> Tensor<4>) {
    let [_, _, height, width] = reference.dims();
    let pad_h = height.div_ceil(multiple) * multiple - height;
    let pad_w = width.div_ceil(multiple) * multiple - width;
    let (top, left) = (pad_h / 2, pad_w / 2);
    let padding = (left, pad_w - left, top, pad_h - top);
    let pad = |x: Tensor<4>| {
        if pad_h == 0 && pad_w == 0 {
            x
        } else {
            x.pad(padding, PadMode::Edge)
        }
    };
    let crop = move |x: Tensor<4>| x.narrow(2, top, height).narrow(3, left, width);
    (pad(reference), pad(target), crop)
}

/// `0, 1, ..., count - 1` as floats on `like`'s device and in its format
/// (f32, or bf16/f16 under mixed precision; see [`crate::precision`]).
pub fn counting<const D: usize>(count: usize, like: &Tensor<D>) -> Tensor<1> {
    Tensor::<1, Int>::arange(0..count as i64, &like.device()).cast(FloatDType::from(like.dtype()))
}
