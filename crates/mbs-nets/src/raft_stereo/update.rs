//! RAFT-Stereo's multi-level update operator (the official `core/update.py`):
//! a motion encoder of the correlation lookup and the current disparity, one
//! convolutional GRU per level exchanging states with its neighbours, the
//! disparity head and the convex-upsampling mask head.

use crate::cpu_conv::Convolve;
use burn::module::Module;
use burn::nn::conv::Conv2d;
use burn::tensor::Device;
use burn::tensor::Tensor;
use burn::tensor::activation::{relu, sigmoid, tanh};
use burn::tensor::module::avg_pool2d;
use burn::tensor::ops::AvgPoolOptions;

use crate::layers::conv;
use crate::upsample::resize_bilinear_aligned;

/// Channels of the motion features (official `encoder_output_dim`).
const MOTION_CHANNELS: usize = 128;

/// The official `BasicMotionEncoder`.
#[derive(Module, Debug)]
pub struct MotionEncoder {
    convc1: Conv2d,
    convc2: Conv2d,
    convf1: Conv2d,
    convf2: Conv2d,
    conv: Conv2d,
}

impl MotionEncoder {
    fn new(correlation_channels: usize, device: &Device) -> Self {
        MotionEncoder {
            convc1: conv(correlation_channels, 64, 1, 1, 0, device),
            convc2: conv(64, 64, 3, 1, 1, device),
            convf1: conv(2, 64, 7, 1, 3, device),
            convf2: conv(64, 64, 3, 1, 1, device),
            conv: conv(128, MOTION_CHANNELS - 2, 3, 1, 1, device),
        }
    }

    /// Motion features `[B, 128, h, w]` of the flow `[B, 2, h, w]` and the
    /// correlation lookup.
    fn forward(&self, flow: Tensor<4>, correlation: Tensor<4>) -> Tensor<4> {
        let c = relu(self.convc1.convolve(correlation));
        let c = relu(self.convc2.convolve(c));
        let f = relu(self.convf1.convolve(flow.clone()));
        let f = relu(self.convf2.convolve(f));
        let out = relu(self.conv.convolve(Tensor::cat(vec![c, f], 1)));
        Tensor::cat(vec![out, flow], 1)
    }
}

/// The official `ConvGRU` (3x3) whose gates also receive precomputed
/// context terms `cz, cr, cq`.
#[derive(Module, Debug)]
pub struct ConvGru {
    convz: Conv2d,
    convr: Conv2d,
    convq: Conv2d,
}

impl ConvGru {
    /// A GRU of `hidden` channels over `input` input channels.
    pub(crate) fn new(hidden: usize, input: usize, device: &Device) -> Self {
        let gate = || conv(hidden + input, hidden, 3, 1, 1, device);
        ConvGru {
            convz: gate(),
            convr: gate(),
            convq: gate(),
        }
    }

    /// The next hidden state from `h`, the context terms and the inputs.
    pub(crate) fn forward(
        &self,
        h: Tensor<4>,
        context: &[Tensor<4>; 3],
        inputs: Vec<Tensor<4>>,
    ) -> Tensor<4> {
        let x = Tensor::cat(inputs, 1);
        let hx = Tensor::cat(vec![h.clone(), x.clone()], 1);
        let z = sigmoid(self.convz.convolve(hx.clone()) + context[0].clone());
        let r = sigmoid(self.convr.convolve(hx) + context[1].clone());
        let q =
            tanh(self.convq.convolve(Tensor::cat(vec![r * h.clone(), x], 1)) + context[2].clone());
        (z.clone().neg() + 1.0) * h + z * q
    }
}

/// The official `FlowHead`: two 3x3 convolutions to a flow update.
#[derive(Module, Debug)]
pub struct FlowHead {
    conv1: Conv2d,
    conv2: Conv2d,
}

/// The convex-upsampling weights head (official `mask`, layers `0` and `2`).
#[derive(Module, Debug)]
pub struct MaskHead {
    conv1: Conv2d,
    conv2: Conv2d,
}

/// The official `BasicMultiUpdateBlock`.
#[derive(Module, Debug)]
pub struct UpdateBlock {
    encoder: MotionEncoder,
    gru08: ConvGru,
    gru16: ConvGru,
    gru32: ConvGru,
    flow_head: FlowHead,
    mask: MaskHead,
    levels: usize,
}

/// Which GRU levels one call of [`UpdateBlock::forward`] updates.
#[derive(Debug, Clone, Copy)]
pub struct LevelsToUpdate {
    /// The 1/4-of-features level (official `iter32`).
    pub coarsest: bool,
    /// The middle level (official `iter16`).
    pub middle: bool,
    /// The finest level, with the motion features (official `iter08`).
    pub finest: bool,
}

/// The GRU states, finest first, and their precomputed context terms.
pub struct GruState {
    /// Hidden state per level.
    pub hidden: Vec<Tensor<4>>,
    /// `cz, cr, cq` per level.
    pub context: Vec<[Tensor<4>; 3]>,
}

impl GruState {
    /// The initial state from the context encoder's `[hidden, context]`
    /// pre-activations per level: `tanh` of the first, and the three gate
    /// terms of `zqr_convs[level](relu(context))` (computed once, as the
    /// official code does).
    pub fn from_context(outputs: Vec<[Tensor<4>; 2]>, zqr_convs: &[Conv2d]) -> Self {
        let mut state = GruState {
            hidden: Vec::with_capacity(outputs.len()),
            context: Vec::with_capacity(outputs.len()),
        };
        for ([hidden, context], zqr) in outputs.into_iter().zip(zqr_convs) {
            state.hidden.push(tanh(hidden));
            let terms = zqr.convolve(relu(context));
            let third = terms.dims()[1] / 3;
            state.context.push([
                terms.clone().narrow(1, 0, third),
                terms.clone().narrow(1, third, third),
                terms.narrow(1, 2 * third, third),
            ]);
        }
        state
    }

    /// Updates the coarse levels chosen by `which` with their GRUs (the
    /// official third and second GRUs of `levels`): each takes the pooled
    /// finer state and, below the coarsest, the resized coarser one.
    pub fn update_coarse(
        &mut self,
        which: LevelsToUpdate,
        levels: usize,
        coarsest: &ConvGru,
        middle: &ConvGru,
    ) {
        let (h, c) = (&mut self.hidden, &self.context);
        if which.coarsest && levels == 3 {
            h[2] = coarsest.forward(h[2].clone(), &c[2], vec![pool2x(h[1].clone())]);
        }
        if which.middle && levels >= 2 {
            let mut inputs = vec![pool2x(h[0].clone())];
            if levels > 2 {
                inputs.push(interp(h[2].clone(), &h[1]));
            }
            h[1] = middle.forward(h[1].clone(), &c[1], inputs);
        }
    }

    /// Updates the finest level with `gru` from the motion features and,
    /// with more than one level, the resized middle state.
    pub fn update_finest(&mut self, levels: usize, gru: &ConvGru, motion: Tensor<4>) {
        let (h, c) = (&mut self.hidden, &self.context);
        let mut inputs = vec![motion];
        if levels > 1 {
            inputs.push(interp(h[1].clone(), &h[0]));
        }
        h[0] = gru.forward(h[0].clone(), &c[0], inputs);
    }
}

/// `avg_pool2d(x, 3, stride=2, padding=1)`, counting the padding.
pub(crate) fn pool2x(x: Tensor<4>) -> Tensor<4> {
    avg_pool2d(
        x,
        AvgPoolOptions::new([3, 3])
            .with_stride([2, 2])
            .with_padding([1, 1]),
    )
}

/// `x` resized to the spatial size of `like` (bilinear, corners aligned).
pub(crate) fn interp(x: Tensor<4>, like: &Tensor<4>) -> Tensor<4> {
    let [_, _, height, width] = like.dims();
    resize_bilinear_aligned(x, height, width)
}

impl UpdateBlock {
    /// The block for `levels` GRU levels of `hidden` channels, a lookup of
    /// `correlation_channels` and a `factor`x upsampling.
    pub fn new(
        hidden: usize,
        levels: usize,
        correlation_channels: usize,
        factor: usize,
        device: &Device,
    ) -> Self {
        let finest_input = MOTION_CHANNELS + if levels > 1 { hidden } else { 0 };
        let middle_input = if levels == 3 { hidden } else { 0 } + hidden;
        UpdateBlock {
            encoder: MotionEncoder::new(correlation_channels, device),
            gru08: ConvGru::new(hidden, finest_input, device),
            gru16: ConvGru::new(hidden, middle_input, device),
            gru32: ConvGru::new(hidden, hidden, device),
            flow_head: FlowHead {
                conv1: conv(hidden, 256, 3, 1, 1, device),
                conv2: conv(256, 2, 3, 1, 1, device),
            },
            mask: MaskHead {
                conv1: conv(hidden, 256, 3, 1, 1, device),
                conv2: conv(256, factor * factor * 9, 1, 1, 0, device),
            },
            levels,
        }
    }

    /// Updates the GRU states of the chosen levels in place; the finest
    /// level needs the `flow` and `correlation` of the current estimate.
    pub fn update(
        &self,
        state: &mut GruState,
        which: LevelsToUpdate,
        motion: Option<(Tensor<4>, Tensor<4>)>,
    ) {
        state.update_coarse(which, self.levels, &self.gru32, &self.gru16);
        if let (true, Some((flow, correlation))) = (which.finest, motion) {
            let motion = self.encoder.forward(flow, correlation);
            state.update_finest(self.levels, &self.gru08, motion);
        }
    }

    /// The flow update `[B, 2, h, w]` and the upsampling weights (scaled by
    /// 1/4, as the official code does) of the finest hidden state.
    pub fn heads(&self, finest: Tensor<4>) -> (Tensor<4>, Tensor<4>) {
        let delta = self
            .flow_head
            .conv2
            .convolve(relu(self.flow_head.conv1.convolve(finest.clone())));
        let mask = self
            .mask
            .conv2
            .convolve(relu(self.mask.conv1.convolve(finest)))
            * 0.25;
        (delta, mask)
    }
}
