//! RAFT-Stereo (Lipson et al. 2021) as a burn module, structurally the
//! official PyTorch implementation (princeton-vl/RAFT-Stereo, `core/`), so
//! its state dicts map one to one ([`crate::official`]).
//!
//! A feature encoder gives 256-channel features of both images at
//! `1 / 2^n_downsample` resolution; their 1-D correlation pyramid is looked
//! up around the current disparity; a context encoder initialises up to
//! three ConvGRU levels whose finest level predicts a disparity update each
//! iteration; convex upsampling brings every estimate to full resolution.
//! The official setting `shared_backbone` and the CUDA correlation kernels
//! are not provided (the default `reg` correlation is).

pub(crate) mod correlation;
pub(crate) mod encoder;
pub(crate) mod update;

use burn::config::Config;
use burn::module::Module;
use burn::nn::conv::Conv2d;
use burn::tensor::{Device, Tensor};

use self::correlation::CorrelationPyramid;
use self::encoder::{ContextEncoder, FeatureEncoder};
use self::update::{GruState, LevelsToUpdate, UpdateBlock};
use super::Backbone;
use super::layers::{conv, counting, pad_to_multiple};
use super::norm::NormKind;
use super::official::OfficialLayout;
use super::upsample::convex_upsample;
use crate::error::NetError;
use crate::ranges;

/// Channels of the matching features (fixed in the official code).
const FEATURE_CHANNELS: usize = 256;

/// Hyper-parameters of [`RaftStereo`], with the official defaults.
#[derive(Config, Debug, PartialEq)]
pub struct RaftStereoConfig {
    /// Channels of every GRU level's hidden state and context (official
    /// `hidden_dims`, which must be equal at every level).
    #[config(default = 128)]
    pub hidden_dim: usize,
    /// GRU levels, 1 to 3 (official `n_gru_layers`).
    #[config(default = 3)]
    pub gru_levels: usize,
    /// Levels of the correlation pyramid (official `corr_levels`).
    #[config(default = 4)]
    pub corr_levels: usize,
    /// Lookup radius at each level (official `corr_radius`).
    #[config(default = 4)]
    pub corr_radius: usize,
    /// The disparity field is at `1 / 2^n_downsample` resolution, 1 to 3.
    #[config(default = 2)]
    pub n_downsample: usize,
    /// Normalisation of the context encoder (official `context_norm`).
    #[config(default = "NormKind::Batch")]
    pub context_norm: NormKind,
    /// Update the coarser GRUs more often (official `slow_fast_gru`).
    #[config(default = false)]
    pub slow_fast_gru: bool,
    /// Update iterations while training (official `train_iters`).
    #[config(default = 16)]
    pub train_iters: usize,
    /// Update iterations for inference and the teacher (official `valid_iters`).
    #[config(default = 32)]
    pub test_iters: usize,
}

impl RaftStereoConfig {
    /// Checks the level counts and widths.
    pub fn validate(&self) -> Result<(), NetError> {
        ranges::require(
            (1..=3).contains(&self.gru_levels),
            "gru_levels",
            self.gru_levels,
            "1, 2 or 3",
        )?;
        ranges::require(
            (1..=3).contains(&self.n_downsample),
            "n_downsample",
            self.n_downsample,
            "1, 2 or 3",
        )?;
        ranges::iterative_network(
            self.hidden_dim,
            (self.corr_levels, self.corr_radius),
            (self.train_iters, self.test_iters),
        )
    }

    /// Builds the network with fresh weights on `device`.
    pub fn init(&self, device: &Device) -> Result<RaftStereo, NetError> {
        self.validate()?;
        let hidden = self.hidden_dim;
        let factor = 1 << self.n_downsample;
        Ok(RaftStereo {
            cnet: ContextEncoder::new(hidden, self.context_norm, self.n_downsample, device),
            update_block: UpdateBlock::new(
                hidden,
                self.gru_levels,
                CorrelationPyramid::channels(self.corr_levels, self.corr_radius),
                factor,
                device,
            ),
            context_zqr_convs: (0..self.gru_levels)
                .map(|_| conv(hidden, hidden * 3, 3, 1, 1, device))
                .collect(),
            fnet: FeatureEncoder::new(
                FEATURE_CHANNELS,
                NormKind::Instance,
                self.n_downsample,
                device,
            ),
            gru_levels: self.gru_levels,
            corr_levels: self.corr_levels,
            corr_radius: self.corr_radius,
            factor,
            slow_fast_gru: self.slow_fast_gru,
            train_iters: self.train_iters,
            test_iters: self.test_iters,
        })
    }
}

/// RAFT-Stereo (see the module documentation).
#[derive(Module, Debug)]
pub struct RaftStereo {
    cnet: ContextEncoder,
    update_block: UpdateBlock,
    context_zqr_convs: Vec<Conv2d>,
    fnet: FeatureEncoder,
    gru_levels: usize,
    corr_levels: usize,
    corr_radius: usize,
    factor: usize,
    slow_fast_gru: bool,
    train_iters: usize,
    test_iters: usize,
}

impl RaftStereo {
    /// The full-resolution disparity after each of `iterations` updates.
    pub fn iterate(
        &self,
        reference: Tensor<4>,
        target: Tensor<4>,
        iterations: usize,
    ) -> Vec<Tensor<4>> {
        let batch = reference.dims()[0];
        let reference = reference * 2.0 - 1.0;
        let target = target * 2.0 - 1.0;
        let mut state = GruState::from_context(
            self.cnet.forward(reference.clone(), self.gru_levels),
            &self.context_zqr_convs,
        );
        let features = self.fnet.forward(Tensor::cat(vec![reference, target], 0));
        let pyramid = CorrelationPyramid::new(
            features.clone().narrow(0, 0, batch),
            features.narrow(0, batch, batch),
            self.corr_levels,
            self.corr_radius,
        );
        let [_, _, height, width] = state.hidden[0].dims();
        let columns = counting(width, &state.hidden[0])
            .reshape([1, 1, 1, width])
            .expand([batch, 1, height, width]);
        let zeros = columns.zeros_like();
        // The official flow is `coords1 - coords0`: x only, negative disparity.
        let mut flow = zeros.clone();
        let mut predictions = Vec::with_capacity(iterations);
        for _ in 0..iterations {
            flow = flow.detach();
            let correlation = pyramid.lookup(columns.clone() + flow.clone());
            if self.slow_fast_gru {
                for middle in [false, true] {
                    let which = LevelsToUpdate {
                        coarsest: self.gru_levels == 3,
                        middle,
                        finest: false,
                    };
                    if which.coarsest || middle {
                        self.update_block.update(&mut state, which, None);
                    }
                }
            }
            let motion = Tensor::cat(vec![flow.clone(), zeros.clone()], 1);
            let which = LevelsToUpdate {
                coarsest: self.gru_levels == 3,
                middle: self.gru_levels >= 2,
                finest: true,
            };
            self.update_block
                .update(&mut state, which, Some((motion, correlation)));
            let (delta, mask) = self.update_block.heads(state.hidden[0].clone());
            flow = flow + delta.narrow(1, 0, 1);
            predictions.push(convex_upsample(flow.clone(), mask, self.factor).neg());
        }
        predictions
    }
}

impl Backbone for RaftStereo {
    /// Sides that are not multiples of 32 are padded by edge replication,
    /// as the official `InputPadder`, and the output cropped back.
    fn disparity(&self, reference: Tensor<4>, target: Tensor<4>) -> Tensor<4> {
        let (reference, target, crop) = pad_to_multiple(reference, target, 32);
        let mut predictions = self.iterate(reference, target, self.test_iters);
        crop(
            predictions
                .pop()
                .expect("at least one iteration (validated)"),
        )
    }

    fn disparities(&self, reference: Tensor<4>, target: Tensor<4>) -> Vec<Tensor<4>> {
        let (reference, target, crop) = pad_to_multiple(reference, target, 32);
        self.iterate(reference, target, self.train_iters)
            .into_iter()
            .map(crop)
            .collect()
    }
}

impl OfficialLayout for RaftStereo {
    /// Burn paths name PyTorch's `nn.Sequential` members: the encoders'
    /// shared `trunk` is not a level of the official keys, a projection's
    /// `conv`/`norm` are `downsample.0`/`.1`, a context head's
    /// `block`/`conv` are `0`/`1`, and the mask head's `conv1`/`conv2` are
    /// `mask.0`/`mask.2`.
    fn official_key(path: &str) -> String {
        let segments: Vec<&str> = path.split('.').filter(|s| *s != "trunk").collect();
        let renamed: Vec<&str> = segments
            .iter()
            .enumerate()
            .map(|(i, &segment)| {
                let parent = if i >= 1 { segments[i - 1] } else { "" };
                let grandparent = if i >= 2 { segments[i - 2] } else { "" };
                match (segment, parent, grandparent) {
                    ("conv", "downsample", _) => "0",
                    ("norm", "downsample", _) => "1",
                    ("block", _, "outputs08" | "outputs16") => "0",
                    ("conv", _, "outputs08" | "outputs16") => "1",
                    ("conv1", "mask", _) => "0",
                    ("conv2", "mask", _) => "2",
                    _ => segment,
                }
            })
            .collect();
        renamed.join(".")
    }
}

#[cfg(test)]
mod tests;
