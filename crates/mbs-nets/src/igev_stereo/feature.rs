//! IGEV-Stereo's feature encoder (the official `Feature`): timm's
//! MobileNetV2 (`mobilenetv2_100`) down to 1/32, then transposed
//! convolutions back up to 1/4 with skip connections. Parameter names follow
//! timm 0.5.4, which the official code was written for.

use crate::cpu_conv::Convolve;
use burn::module::Module;
use burn::nn::PaddingConfig2d;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::tensor::activation::relu6;
use burn::tensor::{Device, Tensor};

use super::blocks::{BasicConv2d, Conv2x, ConvSpec};
use crate::norm::{Norm, NormKind};

/// A convolution without bias with "same" padding (`groups` for depthwise ones).
pub(super) fn conv(
    from: usize,
    to: usize,
    kernel: usize,
    stride: usize,
    groups: usize,
    device: &Device,
) -> Conv2d {
    let padding = kernel / 2;
    Conv2dConfig::new([from, to], [kernel, kernel])
        .with_stride([stride, stride])
        .with_padding(PaddingConfig2d::Explicit(
            padding, padding, padding, padding,
        ))
        .with_groups(groups)
        .with_bias(false)
        .init(device)
}

fn bn(channels: usize, device: &Device) -> Norm {
    Norm::new(NormKind::Batch, channels, 0, device)
}

/// timm's `DepthwiseSeparableConv` (MobileNetV2's first block): depthwise
/// 3x3, ReLU6, pointwise 1x1.
#[derive(Module, Debug)]
pub struct DepthwiseSeparable {
    conv_dw: Conv2d,
    bn1: Norm,
    conv_pw: Conv2d,
    bn2: Norm,
    skip: bool,
}

impl DepthwiseSeparable {
    fn new(from: usize, to: usize, device: &Device) -> Self {
        DepthwiseSeparable {
            conv_dw: conv(from, from, 3, 1, from, device),
            bn1: bn(from, device),
            conv_pw: conv(from, to, 1, 1, 1, device),
            bn2: bn(to, device),
            skip: from == to,
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let y = relu6(self.bn1.forward(self.conv_dw.convolve(x.clone())));
        let y = self.bn2.forward(self.conv_pw.convolve(y));
        if self.skip { y + x } else { y }
    }
}

/// timm's `InvertedResidual`: pointwise expansion by 6, ReLU6, depthwise
/// 3x3 (with the stride), ReLU6, linear pointwise projection; a residual
/// connection when the shape is kept.
#[derive(Module, Debug)]
pub struct InvertedResidual {
    conv_pw: Conv2d,
    bn1: Norm,
    conv_dw: Conv2d,
    bn2: Norm,
    conv_pwl: Conv2d,
    bn3: Norm,
    skip: bool,
}

impl InvertedResidual {
    fn new(from: usize, to: usize, stride: usize, device: &Device) -> Self {
        let mid = from * 6;
        InvertedResidual {
            conv_pw: conv(from, mid, 1, 1, 1, device),
            bn1: bn(mid, device),
            conv_dw: conv(mid, mid, 3, stride, mid, device),
            bn2: bn(mid, device),
            conv_pwl: conv(mid, to, 1, 1, 1, device),
            bn3: bn(to, device),
            skip: stride == 1 && from == to,
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let y = relu6(self.bn1.forward(self.conv_pw.convolve(x.clone())));
        let y = relu6(self.bn2.forward(self.conv_dw.convolve(y)));
        let y = self.bn3.forward(self.conv_pwl.convolve(y));
        if self.skip { y + x } else { y }
    }
}

/// A MobileNetV2 stage: `count` inverted residuals, the first with the stride.
fn stage(
    from: usize,
    to: usize,
    count: usize,
    stride: usize,
    device: &Device,
) -> Vec<InvertedResidual> {
    (0..count)
        .map(|i| {
            let (from, stride) = if i == 0 { (from, stride) } else { (to, 1) };
            InvertedResidual::new(from, to, stride, device)
        })
        .collect()
}

fn run(stages: &[Vec<InvertedResidual>], x: Tensor<4>) -> Tensor<4> {
    stages.iter().flatten().fold(x, |x, block| block.forward(x))
}

/// The feature encoder (see the module documentation). Its outputs have
/// 48, 64, 192 and 160 channels at 1/4, 1/8, 1/16 and 1/32 resolution.
#[derive(Module, Debug)]
pub struct Feature {
    conv_stem: Conv2d,
    bn1: Norm,
    block0: Vec<Vec<DepthwiseSeparable>>,
    block1: Vec<Vec<InvertedResidual>>,
    block2: Vec<Vec<InvertedResidual>>,
    block3: Vec<Vec<InvertedResidual>>,
    block4: Vec<Vec<InvertedResidual>>,
    deconv32_16: Conv2x,
    deconv16_8: Conv2x,
    deconv8_4: Conv2x,
    conv4: BasicConv2d,
}

impl Feature {
    /// The encoder with fresh weights.
    pub fn new(device: &Device) -> Self {
        let instance = NormKind::Instance;
        Feature {
            conv_stem: conv(3, 32, 3, 2, 1, device),
            bn1: bn(32, device),
            block0: vec![vec![DepthwiseSeparable::new(32, 16, device)]],
            block1: vec![stage(16, 24, 2, 2, device)],
            block2: vec![stage(24, 32, 3, 2, device)],
            block3: vec![stage(32, 64, 4, 2, device), stage(64, 96, 3, 1, device)],
            block4: vec![stage(96, 160, 3, 2, device)],
            deconv32_16: Conv2x::new(160, 96, instance, device),
            deconv16_8: Conv2x::new(192, 32, instance, device),
            deconv8_4: Conv2x::new(64, 24, instance, device),
            conv4: BasicConv2d::new(48, 48, instance, ConvSpec::same(3), device),
        }
    }

    /// Features of images in `[-1, 1]` (sides multiples of 32) at 1/4, 1/8,
    /// 1/16 and 1/32 resolution.
    pub fn forward(&self, x: Tensor<4>) -> [Tensor<4>; 4] {
        let x = relu6(self.bn1.forward(self.conv_stem.convolve(x)));
        let x2 = self.block0.iter().flatten().fold(x, |x, b| b.forward(x));
        let x4 = run(&self.block1, x2);
        let x8 = run(&self.block2, x4.clone());
        let x16 = run(&self.block3, x8.clone());
        let x32 = run(&self.block4, x16.clone());
        let x16 = self.deconv32_16.forward(x32.clone(), x16);
        let x8 = self.deconv16_8.forward(x16.clone(), x8);
        let x4 = self.conv4.forward(self.deconv8_4.forward(x8.clone(), x4));
        [x4, x8, x16, x32]
    }
}
