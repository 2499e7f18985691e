//! IGEV-Stereo's convolution blocks (the official `core/submodule.py`):
//! convolutions without bias followed by a normalisation and a leaky ReLU
//! (2-D and 3-D, plain and transposed), the up-and-merge `Conv2x` pairs,
//! the feature-guided excitation of a cost volume and the 3-D hourglass
//! that aggregates it.

use crate::cpu_conv::Convolve;
use burn::module::Module;
use burn::nn::PaddingConfig2d;
use burn::nn::PaddingConfig3d;
use burn::nn::conv::{
    Conv2d, Conv2dConfig, Conv3d, Conv3dConfig, ConvTranspose2d, ConvTranspose2dConfig,
    ConvTranspose3d, ConvTranspose3dConfig,
};
use burn::tensor::activation::{leaky_relu, sigmoid};
use burn::tensor::{Device, Tensor};

use crate::layers::conv;
use crate::norm::{Norm, NormKind};

/// PyTorch's `nn.LeakyReLU()` slope.
const LEAKY_SLOPE: f64 = 0.01;

/// A 2-D convolution or transposed convolution without bias.
#[derive(Module, Debug)]
pub enum Conv2dAny {
    /// `nn.Conv2d`.
    Plain(Conv2d),
    /// `nn.ConvTranspose2d`.
    Transposed(ConvTranspose2d),
}

impl Conv2dAny {
    fn new(
        from: usize,
        to: usize,
        kernel: usize,
        stride: usize,
        padding: usize,
        transposed: bool,
        device: &Device,
    ) -> Self {
        if transposed {
            Conv2dAny::Transposed(
                ConvTranspose2dConfig::new([from, to], [kernel, kernel])
                    .with_stride([stride, stride])
                    .with_padding([padding, padding])
                    .with_bias(false)
                    .init(device),
            )
        } else {
            Conv2dAny::Plain(
                Conv2dConfig::new([from, to], [kernel, kernel])
                    .with_stride([stride, stride])
                    .with_padding(PaddingConfig2d::Explicit(
                        padding, padding, padding, padding,
                    ))
                    .with_bias(false)
                    .init(device),
            )
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        match self {
            Conv2dAny::Plain(c) => c.convolve(x),
            Conv2dAny::Transposed(c) => c.forward(x),
        }
    }
}

/// The official `BasicConv` (2-D, batch norm) and `BasicConv_IN` (2-D,
/// instance norm): convolution, optional normalisation, optional leaky ReLU.
/// Its batch norm exists (and loads) even where it is not applied.
#[derive(Module, Debug)]
pub struct BasicConv2d {
    conv: Conv2dAny,
    bn: Norm,
    normalise: bool,
    activate: bool,
}

/// Options of a [`BasicConv2d`] or [`BasicConv3d`].
#[derive(Debug, Clone, Copy)]
pub struct ConvSpec {
    /// Kernel side.
    pub kernel: usize,
    /// Stride.
    pub stride: usize,
    /// Padding.
    pub padding: usize,
    /// Transposed convolution.
    pub transposed: bool,
    /// Apply the normalisation.
    pub normalise: bool,
    /// Apply the leaky ReLU.
    pub activate: bool,
}

impl ConvSpec {
    /// A `kernel` x `kernel` convolution with "same" padding, stride 1,
    /// normalised and activated.
    pub fn same(kernel: usize) -> Self {
        ConvSpec {
            kernel,
            stride: 1,
            padding: kernel / 2,
            transposed: false,
            normalise: true,
            activate: true,
        }
    }

    /// A 4x4 transposed convolution of stride 2 (doubles the size).
    pub fn up() -> Self {
        ConvSpec {
            kernel: 4,
            stride: 2,
            padding: 1,
            transposed: true,
            normalise: true,
            activate: true,
        }
    }

    /// A 3x3 convolution of stride 2 (halves the size).
    pub fn down() -> Self {
        ConvSpec {
            stride: 2,
            ..ConvSpec::same(3)
        }
    }
}

impl BasicConv2d {
    /// The block from `from` to `to` channels with `norm` (batch or instance).
    pub fn new(from: usize, to: usize, norm: NormKind, spec: ConvSpec, device: &Device) -> Self {
        BasicConv2d {
            conv: Conv2dAny::new(
                from,
                to,
                spec.kernel,
                spec.stride,
                spec.padding,
                spec.transposed,
                device,
            ),
            bn: Norm::new(norm, to, 0, device),
            normalise: spec.normalise,
            activate: spec.activate,
        }
    }

    /// Convolution, normalisation, activation.
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let mut x = self.conv.forward(x);
        if self.normalise {
            x = self.bn.forward(x);
        }
        if self.activate {
            x = leaky_relu(x, LEAKY_SLOPE);
        }
        x
    }
}

/// A 3-D convolution or transposed convolution without bias.
#[derive(Module, Debug)]
pub enum Conv3dAny {
    /// `nn.Conv3d`.
    Plain(Conv3d),
    /// `nn.ConvTranspose3d`.
    Transposed(ConvTranspose3d),
}

/// The official `BasicConv` in 3-D (batch norm over the volume).
#[derive(Module, Debug)]
pub struct BasicConv3d {
    conv: Conv3dAny,
    bn: Norm,
    normalise: bool,
    activate: bool,
}

impl BasicConv3d {
    /// The block from `from` to `to` channels.
    pub fn new(from: usize, to: usize, spec: ConvSpec, device: &Device) -> Self {
        let k = spec.kernel;
        let conv = if spec.transposed {
            Conv3dAny::Transposed(
                ConvTranspose3dConfig::new([from, to], [k, k, k])
                    .with_stride([spec.stride; 3])
                    .with_padding([spec.padding; 3])
                    .with_bias(false)
                    .init(device),
            )
        } else {
            Conv3dAny::Plain(
                Conv3dConfig::new([from, to], [k, k, k])
                    .with_stride([spec.stride; 3])
                    .with_padding(PaddingConfig3d::Explicit(
                        spec.padding,
                        spec.padding,
                        spec.padding,
                    ))
                    .with_bias(false)
                    .init(device),
            )
        };
        BasicConv3d {
            conv,
            bn: Norm::new(NormKind::Batch, to, 0, device),
            normalise: spec.normalise,
            activate: spec.activate,
        }
    }

    /// Convolution, normalisation, activation of `[B, C, D, H, W]`.
    pub fn forward(&self, x: Tensor<5>) -> Tensor<5> {
        let mut x = match &self.conv {
            Conv3dAny::Plain(c) => c.convolve(x),
            Conv3dAny::Transposed(c) => c.forward(x),
        };
        if self.normalise {
            let [b, c, d, h, w] = x.dims();
            x = self
                .bn
                .forward(x.reshape([b, c, d * h, w]))
                .reshape([b, c, d, h, w]);
        }
        if self.activate {
            x = leaky_relu(x, LEAKY_SLOPE);
        }
        x
    }
}

/// The official `Conv2x` / `Conv2x_IN` (2-D, transposed, concatenating):
/// double `x`, concatenate the skip `rem` and convolve.
#[derive(Module, Debug)]
pub struct Conv2x {
    conv1: BasicConv2d,
    conv2: BasicConv2d,
}

impl Conv2x {
    /// From `from` channels to `2 to` (with the skip's `to` channels).
    pub fn new(from: usize, to: usize, norm: NormKind, device: &Device) -> Self {
        Conv2x {
            conv1: BasicConv2d::new(from, to, norm, ConvSpec::up(), device),
            conv2: BasicConv2d::new(2 * to, 2 * to, norm, ConvSpec::same(3), device),
        }
    }

    /// `conv2(cat(conv1(x), rem))`; `x` must double to `rem`'s size.
    pub fn forward(&self, x: Tensor<4>, rem: Tensor<4>) -> Tensor<4> {
        let x = self.conv1.forward(x);
        self.conv2.forward(Tensor::cat(vec![x, rem], 1))
    }
}

/// The official `FeatureAtt`: `sigmoid(f(features))` weighs every
/// disparity plane of a cost volume (`feat_att.0`, `feat_att.1`).
#[derive(Module, Debug)]
pub struct FeatureAtt {
    reduce: BasicConv2d,
    excite: Conv2d,
}

impl FeatureAtt {
    /// For a volume of `volume` channels and features of `features` channels.
    pub fn new(volume: usize, features: usize, device: &Device) -> Self {
        FeatureAtt {
            reduce: BasicConv2d::new(
                features,
                features / 2,
                NormKind::Batch,
                ConvSpec::same(1),
                device,
            ),
            excite: conv(features / 2, volume, 1, 1, 0, device),
        }
    }

    /// The volume `[B, C, D, H, W]` weighted by the features `[B, F, H, W]`.
    pub fn forward(&self, volume: Tensor<5>, features: Tensor<4>) -> Tensor<5> {
        let weights = self.excite.convolve(self.reduce.forward(features));
        let [b, c, h, w] = weights.dims();
        sigmoid(weights).reshape([b, c, 1, h, w]) * volume
    }
}

/// Two 3-D blocks, the first of stride 2.
fn down3d(from: usize, to: usize, device: &Device) -> Vec<BasicConv3d> {
    vec![
        BasicConv3d::new(from, to, ConvSpec::down(), device),
        BasicConv3d::new(to, to, ConvSpec::same(3), device),
    ]
}

/// A 1x1x1 reduction and two 3x3x3 blocks.
fn aggregate3d(from: usize, to: usize, device: &Device) -> Vec<BasicConv3d> {
    vec![
        BasicConv3d::new(from, to, ConvSpec::same(1), device),
        BasicConv3d::new(to, to, ConvSpec::same(3), device),
        BasicConv3d::new(to, to, ConvSpec::same(3), device),
    ]
}

fn run3d(blocks: &[BasicConv3d], x: Tensor<5>) -> Tensor<5> {
    blocks.iter().fold(x, |x, block| block.forward(x))
}

/// The official `hourglass`: a 3-D encoder-decoder over the cost volume,
/// guided at every scale by the left image's features.
#[derive(Module, Debug)]
pub struct Hourglass {
    conv1: Vec<BasicConv3d>,
    conv2: Vec<BasicConv3d>,
    conv3: Vec<BasicConv3d>,
    conv3_up: BasicConv3d,
    conv2_up: BasicConv3d,
    conv1_up: BasicConv3d,
    agg_0: Vec<BasicConv3d>,
    agg_1: Vec<BasicConv3d>,
    feature_att_8: FeatureAtt,
    feature_att_16: FeatureAtt,
    feature_att_32: FeatureAtt,
    feature_att_up_16: FeatureAtt,
    feature_att_up_8: FeatureAtt,
}

impl Hourglass {
    /// The hourglass over `c` volume channels.
    pub fn new(c: usize, device: &Device) -> Self {
        Hourglass {
            conv1: down3d(c, 2 * c, device),
            conv2: down3d(2 * c, 4 * c, device),
            conv3: down3d(4 * c, 6 * c, device),
            conv3_up: BasicConv3d::new(6 * c, 4 * c, ConvSpec::up(), device),
            conv2_up: BasicConv3d::new(4 * c, 2 * c, ConvSpec::up(), device),
            conv1_up: BasicConv3d::new(
                2 * c,
                8,
                ConvSpec {
                    normalise: false,
                    activate: false,
                    ..ConvSpec::up()
                },
                device,
            ),
            agg_0: aggregate3d(8 * c, 4 * c, device),
            agg_1: aggregate3d(4 * c, 2 * c, device),
            feature_att_8: FeatureAtt::new(2 * c, 64, device),
            feature_att_16: FeatureAtt::new(4 * c, 192, device),
            feature_att_32: FeatureAtt::new(6 * c, 160, device),
            feature_att_up_16: FeatureAtt::new(4 * c, 192, device),
            feature_att_up_8: FeatureAtt::new(2 * c, 64, device),
        }
    }

    /// The aggregated volume of `x`, with the features at 1/4 to 1/32.
    pub fn forward(&self, x: Tensor<5>, features: &[Tensor<4>; 4]) -> Tensor<5> {
        let conv1 = self
            .feature_att_8
            .forward(run3d(&self.conv1, x), features[1].clone());
        let conv2 = self
            .feature_att_16
            .forward(run3d(&self.conv2, conv1.clone()), features[2].clone());
        let conv3 = self
            .feature_att_32
            .forward(run3d(&self.conv3, conv2.clone()), features[3].clone());
        let conv2 = Tensor::cat(vec![self.conv3_up.forward(conv3), conv2], 1);
        let conv2 = self
            .feature_att_up_16
            .forward(run3d(&self.agg_0, conv2), features[2].clone());
        let conv1 = Tensor::cat(vec![self.conv2_up.forward(conv2), conv1], 1);
        let conv1 = self
            .feature_att_up_8
            .forward(run3d(&self.agg_1, conv1), features[1].clone());
        self.conv1_up.forward(conv1)
    }
}
