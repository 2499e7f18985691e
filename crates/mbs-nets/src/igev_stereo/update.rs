//! IGEV-Stereo's update operator (the official `core/update.py`): RAFT's
//! multi-level ConvGRU driven by a motion encoder of the geometry lookup
//! and the disparity, a disparity head and the features of the upsampling
//! weights.

use crate::cpu_conv::Convolve;
use burn::module::Module;
use burn::nn::conv::Conv2d;
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor};

use crate::layers::conv;
use crate::raft_stereo::update::{ConvGru, GruState, LevelsToUpdate};

/// Channels of the motion features.
const MOTION_CHANNELS: usize = 128;

/// The official `BasicMotionEncoder` of IGEV-Stereo.
#[derive(Module, Debug)]
pub struct MotionEncoder {
    convc1: Conv2d,
    convc2: Conv2d,
    convd1: Conv2d,
    convd2: Conv2d,
    conv: Conv2d,
}

impl MotionEncoder {
    fn forward(&self, disparity: Tensor<4>, lookup: Tensor<4>) -> Tensor<4> {
        let c = relu(self.convc2.convolve(relu(self.convc1.convolve(lookup))));
        let d = relu(
            self.convd2
                .convolve(relu(self.convd1.convolve(disparity.clone()))),
        );
        let out = relu(self.conv.convolve(Tensor::cat(vec![c, d], 1)));
        Tensor::cat(vec![out, disparity], 1)
    }
}

/// The official `DispHead`.
#[derive(Module, Debug)]
pub struct DispHead {
    conv1: Conv2d,
    conv2: Conv2d,
}

/// The official `BasicMultiUpdateBlock` of IGEV-Stereo.
#[derive(Module, Debug)]
pub struct UpdateBlock {
    encoder: MotionEncoder,
    gru04: ConvGru,
    gru08: ConvGru,
    gru16: ConvGru,
    disp_head: DispHead,
    mask_feat_4: Vec<Conv2d>,
    levels: usize,
}

impl UpdateBlock {
    /// The block for `levels` GRU levels of `hidden` channels and a lookup of
    /// `lookup_channels`.
    pub fn new(hidden: usize, levels: usize, lookup_channels: usize, device: &Device) -> Self {
        let finest_input = MOTION_CHANNELS + if levels > 1 { hidden } else { 0 };
        let middle_input = if levels == 3 { hidden } else { 0 } + hidden;
        UpdateBlock {
            encoder: MotionEncoder {
                convc1: conv(lookup_channels, 64, 1, 1, 0, device),
                convc2: conv(64, 64, 3, 1, 1, device),
                convd1: conv(1, 64, 7, 1, 3, device),
                convd2: conv(64, 64, 3, 1, 1, device),
                conv: conv(128, MOTION_CHANNELS - 1, 3, 1, 1, device),
            },
            gru04: ConvGru::new(hidden, finest_input, device),
            gru08: ConvGru::new(hidden, middle_input, device),
            gru16: ConvGru::new(hidden, hidden, device),
            disp_head: DispHead {
                conv1: conv(hidden, 256, 3, 1, 1, device),
                conv2: conv(256, 1, 3, 1, 1, device),
            },
            mask_feat_4: vec![conv(hidden, 32, 3, 1, 1, device)],
            levels,
        }
    }

    /// One update of the chosen levels; returns the upsampling features
    /// (`[B, 32, h, w]`) and the disparity update of the finest level.
    pub fn update(
        &self,
        state: &mut GruState,
        which: LevelsToUpdate,
        disparity: Tensor<4>,
        lookup: Tensor<4>,
    ) -> (Tensor<4>, Tensor<4>) {
        state.update_coarse(which, self.levels, &self.gru16, &self.gru08);
        let motion = self.encoder.forward(disparity, lookup);
        state.update_finest(self.levels, &self.gru04, motion);
        let h = &state.hidden;
        let delta = self
            .disp_head
            .conv2
            .convolve(relu(self.disp_head.conv1.convolve(h[0].clone())));
        let features = relu(self.mask_feat_4[0].convolve(h[0].clone()));
        (features, delta)
    }
}
