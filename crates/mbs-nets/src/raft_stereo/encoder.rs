//! RAFT-Stereo's feature and context encoders (the official
//! `core/extractor.py`): a 7x7 stem and pairs of residual blocks at 64, 96
//! and 128 channels down to `1 / 2^n_downsample` resolution; the context
//! encoder goes on to 1/2 and 1/4 of that for the coarser GRU levels.

use crate::cpu_conv::Convolve;
use burn::module::Module;
use burn::nn::conv::Conv2d;
use burn::tensor::Device;
use burn::tensor::Tensor;
use burn::tensor::activation::relu;

use crate::layers::conv;
use crate::norm::{Norm, NormKind};

/// The official `ResidualBlock`: two 3x3 convolutions with normalisation and
/// a 1x1 projection of the input when the shape changes.
#[derive(Module, Debug)]
pub struct ResidualBlock {
    conv1: Conv2d,
    norm1: Norm,
    conv2: Conv2d,
    norm2: Norm,
    downsample: Option<Projection>,
}

/// The official `downsample` sequence: a strided 1x1 convolution (`0`) and
/// its normalisation (`1`, also registered as `norm3`).
#[derive(Module, Debug)]
pub struct Projection {
    conv: Conv2d,
    norm: Norm,
}

impl ResidualBlock {
    /// A block from `from` to `to` channels with the given stride.
    pub fn new(from: usize, to: usize, norm: NormKind, stride: usize, device: &Device) -> Self {
        let groups = to / 8;
        let downsample = (stride != 1 || from != to).then(|| Projection {
            conv: conv(from, to, 1, stride, 0, device),
            norm: Norm::new(norm, to, groups, device),
        });
        ResidualBlock {
            conv1: conv(from, to, 3, stride, 1, device),
            norm1: Norm::new(norm, to, groups, device),
            conv2: conv(to, to, 3, 1, 1, device),
            norm2: Norm::new(norm, to, groups, device),
            downsample,
        }
    }

    /// `relu(x' + y)` with `y` the two convolutions and `x'` the projected input.
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let y = relu(self.norm1.forward(self.conv1.convolve(x.clone())));
        let y = relu(self.norm2.forward(self.conv2.convolve(y)));
        let x = match &self.downsample {
            Some(projection) => projection.norm.forward(projection.conv.convolve(x)),
            None => x,
        };
        relu(x + y)
    }
}

/// Two residual blocks, the first with the stride (the official `_make_layer`).
fn layer(
    from: usize,
    to: usize,
    norm: NormKind,
    stride: usize,
    device: &Device,
) -> Vec<ResidualBlock> {
    vec![
        ResidualBlock::new(from, to, norm, stride, device),
        ResidualBlock::new(to, to, norm, 1, device),
    ]
}

fn run_layer(blocks: &[ResidualBlock], x: Tensor<4>) -> Tensor<4> {
    blocks.iter().fold(x, |x, block| block.forward(x))
}

/// The stem and the three residual layers shared by both encoders.
#[derive(Module, Debug)]
pub struct Trunk {
    conv1: Conv2d,
    norm1: Norm,
    layer1: Vec<ResidualBlock>,
    layer2: Vec<ResidualBlock>,
    layer3: Vec<ResidualBlock>,
}

impl Trunk {
    fn new(norm: NormKind, downsample: usize, device: &Device) -> Self {
        let stride = |level: usize| 1 + usize::from(downsample > level);
        Trunk {
            conv1: conv(3, 64, 7, stride(2), 3, device),
            norm1: Norm::new(norm, 64, 8, device),
            layer1: layer(64, 64, norm, 1, device),
            layer2: layer(64, 96, norm, stride(1), device),
            layer3: layer(96, 128, norm, stride(0), device),
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let x = relu(self.norm1.forward(self.conv1.convolve(x)));
        let x = run_layer(&self.layer1, x);
        let x = run_layer(&self.layer2, x);
        run_layer(&self.layer3, x)
    }
}

/// The feature encoder (official `BasicEncoder`, `fnet`): 256 channels at
/// `1 / 2^downsample` resolution, instance-normalised.
#[derive(Module, Debug)]
pub struct FeatureEncoder {
    trunk: Trunk,
    conv2: Conv2d,
}

impl FeatureEncoder {
    /// The encoder with `output` channels.
    pub fn new(output: usize, norm: NormKind, downsample: usize, device: &Device) -> Self {
        FeatureEncoder {
            trunk: Trunk::new(norm, downsample, device),
            conv2: conv(128, output, 1, 1, 0, device),
        }
    }

    /// Features of `images` (`[B, 3, H, W]` in `[-1, 1]`).
    pub fn forward(&self, images: Tensor<4>) -> Tensor<4> {
        self.conv2.convolve(self.trunk.forward(images))
    }
}

/// A residual block and a 3x3 convolution (one of the official `outputs08`
/// and `outputs16` heads: `0` and `1`).
#[derive(Module, Debug)]
pub struct ContextHead {
    block: ResidualBlock,
    conv: Conv2d,
}

impl ContextHead {
    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        self.conv.convolve(self.block.forward(x))
    }
}

/// The context encoder (official `MultiBasicEncoder`, `cnet`): for each GRU
/// level, the initial hidden state and the context features.
#[derive(Module, Debug)]
pub struct ContextEncoder {
    trunk: Trunk,
    layer4: Vec<ResidualBlock>,
    layer5: Vec<ResidualBlock>,
    outputs08: Vec<ContextHead>,
    outputs16: Vec<ContextHead>,
    outputs32: Vec<Conv2d>,
}

impl ContextEncoder {
    /// Two outputs (hidden state, context) of `hidden` channels per level.
    pub fn new(hidden: usize, norm: NormKind, downsample: usize, device: &Device) -> Self {
        let head = || ContextHead {
            block: ResidualBlock::new(128, 128, norm, 1, device),
            conv: conv(128, hidden, 3, 1, 1, device),
        };
        ContextEncoder {
            trunk: Trunk::new(norm, downsample, device),
            layer4: layer(128, 128, norm, 2, device),
            layer5: layer(128, 128, norm, 2, device),
            outputs08: vec![head(), head()],
            outputs16: vec![head(), head()],
            outputs32: vec![
                conv(128, hidden, 3, 1, 1, device),
                conv(128, hidden, 3, 1, 1, device),
            ],
        }
    }

    /// `[hidden state, context]` pre-activations of the `levels` finest GRU
    /// levels, finest first.
    pub fn forward(&self, images: Tensor<4>, levels: usize) -> Vec<[Tensor<4>; 2]> {
        let pair = |x: &Tensor<4>, heads: &[ContextHead]| {
            [heads[0].forward(x.clone()), heads[1].forward(x.clone())]
        };
        let x = self.trunk.forward(images);
        let mut outputs = vec![pair(&x, &self.outputs08)];
        if levels >= 2 {
            let y = run_layer(&self.layer4, x);
            outputs.push(pair(&y, &self.outputs16));
            if levels >= 3 {
                let z = run_layer(&self.layer5, y);
                outputs.push([
                    self.outputs32[0].convolve(z.clone()),
                    self.outputs32[1].convolve(z),
                ]);
            }
        }
        outputs
    }
}
