//! Small building blocks shared by the official networks.

use burn::nn::PaddingConfig2d;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::tensor::Device;

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
