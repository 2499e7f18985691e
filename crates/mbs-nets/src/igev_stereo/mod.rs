//! IGEV-Stereo (Xu et al. 2023), the paper's main backbone, as a burn
//! module, structurally the official PyTorch implementation (gangweiX/IGEV,
//! `IGEV-Stereo/core/`), so its state dicts map one to one
//! ([`crate::official`]).
//!
//! A MobileNetV2 feature encoder gives matching features at 1/4
//! resolution; their group-wise correlation volume is aggregated by a 3-D
//! hourglass into a geometry encoding volume, whose soft-argmin is the
//! initial disparity; RAFT-Stereo's multi-level ConvGRU then refines it
//! with lookups of the geometry volume and of the all-pairs correlation,
//! and learned context upsampling brings every estimate to full
//! resolution. Batch norm is frozen everywhere (the official training
//! freezes only the 2-D ones). Sides must be multiples of 32;
//! [`Backbone::disparity`] pads other sizes as the official `InputPadder`.

mod blocks;
mod feature;
mod geometry;
mod update;

use crate::cpu_conv::Convolve;
use burn::config::Config;
use burn::module::Module;
use burn::nn::PaddingConfig3d;
use burn::nn::conv::{Conv2d, Conv3d, Conv3dConfig, ConvTranspose2d, ConvTranspose2dConfig};
use burn::tensor::activation::{relu, softmax};
use burn::tensor::{Device, Tensor};

use self::blocks::{BasicConv2d, BasicConv3d, Conv2x, ConvSpec, FeatureAtt, Hourglass};
use self::feature::Feature;
use self::geometry::{GeoEncoding, context_upsample, group_correlation_volume, regress_disparity};
use self::update::UpdateBlock;
use super::Backbone;
use super::layers::{conv, pad_to_multiple};
use super::norm::{Norm, NormKind};
use super::official::OfficialLayout;
use super::raft_stereo::RaftStereo;
use super::raft_stereo::encoder::ContextEncoder;
use super::raft_stereo::update::{GruState, LevelsToUpdate};
use crate::error::NetError;
use crate::ranges;

/// Channel groups of the correlation volume (fixed in the official code).
const GROUPS: usize = 8;

/// Hyper-parameters of [`IgevStereo`], with the official defaults.
#[derive(Config, Debug, PartialEq)]
pub struct IgevStereoConfig {
    /// Channels of every GRU level (official `hidden_dims`, equal at every level).
    #[config(default = 128)]
    pub hidden_dim: usize,
    /// GRU levels, 1 to 3 (official `n_gru_layers`).
    #[config(default = 3)]
    pub gru_levels: usize,
    /// Levels of the geometry pyramid (official `corr_levels`).
    #[config(default = 2)]
    pub corr_levels: usize,
    /// Lookup radius (official `corr_radius`).
    #[config(default = 4)]
    pub corr_radius: usize,
    /// Largest disparity of the cost volume, a multiple of 32 (official `max_disp`).
    #[config(default = 192)]
    pub max_disp: usize,
    /// Update iterations while training (official `train_iters`).
    #[config(default = 22)]
    pub train_iters: usize,
    /// Update iterations for inference and the teacher (official `valid_iters`).
    #[config(default = 32)]
    pub test_iters: usize,
}

impl IgevStereoConfig {
    /// Checks the levels, range and iteration counts.
    pub fn validate(&self) -> Result<(), NetError> {
        ranges::require(
            (1..=3).contains(&self.gru_levels),
            "gru_levels",
            self.gru_levels,
            "1, 2 or 3",
        )?;
        ranges::require(
            self.max_disp >= 32
                && self.max_disp.is_multiple_of(32)
                && self.max_disp <= ranges::MAX_DISPARITY,
            "max_disp",
            self.max_disp,
            format!("a multiple of 32 from 32 to {}", ranges::MAX_DISPARITY),
        )?;
        ranges::iterative_network(
            self.hidden_dim,
            (self.corr_levels, self.corr_radius),
            (self.train_iters, self.test_iters),
        )
    }

    /// Builds the network with fresh weights on `device`.
    pub fn init(&self, device: &Device) -> Result<IgevStereo, NetError> {
        self.validate()?;
        let hidden = self.hidden_dim;
        let instance = NormKind::Instance;
        let stem = |from: usize, to: usize, stride: usize| Stem::new(from, to, stride, device);
        let spx = || upsampling_weights_head(device);
        Ok(IgevStereo {
            cnet: ContextEncoder::new(hidden, NormKind::Batch, 2, device),
            update_block: UpdateBlock::new(
                hidden,
                self.gru_levels,
                GeoEncoding::channels(self.corr_levels, self.corr_radius, GROUPS),
                device,
            ),
            context_zqr_convs: (0..self.gru_levels)
                .map(|_| conv(hidden, hidden * 3, 3, 1, 1, device))
                .collect(),
            feature: Feature::new(device),
            stem_2: stem(3, 32, 2),
            stem_4: stem(32, 48, 2),
            spx: spx(),
            spx_2: Conv2x::new(24, 32, instance, device),
            spx_4: stem(96, 24, 1),
            spx_2_gru: Conv2x::new(32, 32, NormKind::Batch, device),
            spx_gru: spx(),
            conv: BasicConv2d::new(96, 96, instance, ConvSpec::same(3), device),
            desc: conv(96, 96, 1, 1, 0, device),
            corr_stem: BasicConv3d::new(GROUPS, GROUPS, ConvSpec::same(3), device),
            corr_feature_att: FeatureAtt::new(GROUPS, 96, device),
            cost_agg: Hourglass::new(GROUPS, device),
            classifier: Conv3dConfig::new([GROUPS, 1], [3, 3, 3])
                .with_padding(PaddingConfig3d::Explicit(1, 1, 1))
                .with_bias(false)
                .init(device),
            gru_levels: self.gru_levels,
            corr_levels: self.corr_levels,
            corr_radius: self.corr_radius,
            candidates: self.max_disp / 4,
            train_iters: self.train_iters,
            test_iters: self.test_iters,
        })
    }
}

/// A strided `BasicConv_IN`, a plain 3x3 convolution, instance norm and
/// ReLU (the official `stem_2`, `stem_4` and `spx_4` sequences: `0`, `1`).
#[derive(Module, Debug)]
pub struct Stem {
    conv_in: BasicConv2d,
    conv: Conv2d,
    norm: Norm,
}

impl Stem {
    /// A stem from `from` to `to` channels whose first convolution has
    /// stride `stride`.
    fn new(from: usize, to: usize, stride: usize, device: &Device) -> Stem {
        let instance = NormKind::Instance;
        Stem {
            conv_in: BasicConv2d::new(
                from,
                to,
                instance,
                ConvSpec {
                    stride,
                    ..ConvSpec::same(3)
                },
                device,
            ),
            conv: feature::conv(to, to, 3, 1, 1, device),
            norm: Norm::new(instance, to, 0, device),
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        relu(
            self.norm
                .forward(self.conv.convolve(self.conv_in.forward(x))),
        )
    }
}

/// IGEV-Stereo (see the module documentation).
#[derive(Module, Debug)]
pub struct IgevStereo {
    cnet: ContextEncoder,
    update_block: UpdateBlock,
    context_zqr_convs: Vec<Conv2d>,
    feature: Feature,
    stem_2: Stem,
    stem_4: Stem,
    spx: Vec<ConvTranspose2d>,
    spx_2: Conv2x,
    spx_4: Stem,
    spx_2_gru: Conv2x,
    spx_gru: Vec<ConvTranspose2d>,
    conv: BasicConv2d,
    desc: Conv2d,
    corr_stem: BasicConv3d,
    corr_feature_att: FeatureAtt,
    cost_agg: Hourglass,
    classifier: Conv3d,
    gru_levels: usize,
    corr_levels: usize,
    corr_radius: usize,
    candidates: usize,
    train_iters: usize,
    test_iters: usize,
}

/// The official `spx` and `spx_gru`: a transposed convolution from 64
/// channels to the 9 weights of each pixel's convex upsampling.
fn upsampling_weights_head(device: &Device) -> Vec<ConvTranspose2d> {
    vec![
        ConvTranspose2dConfig::new([64, 9], [4, 4])
            .with_stride([2, 2])
            .with_padding([1, 1])
            .init(device),
    ]
}

/// Splits a batch of `2 batch` items into its two halves.
fn halves(x: Tensor<4>, batch: usize) -> (Tensor<4>, Tensor<4>) {
    (x.clone().narrow(0, 0, batch), x.narrow(0, batch, batch))
}

/// What [`IgevStereo::iterate`] returns.
pub struct IgevOutput {
    /// The initial disparity (from the geometry encoding volume) at full
    /// resolution, when asked for.
    pub initial: Option<Tensor<4>>,
    /// The full-resolution disparity after each update.
    pub iterations: Vec<Tensor<4>>,
}

impl IgevStereo {
    /// The disparity after each of `iterations` updates of images in
    /// `[0, 1]` whose sides are multiples of 32, and with `initial` the
    /// upsampled initial disparity (the official training outputs).
    pub fn iterate(
        &self,
        reference: Tensor<4>,
        target: Tensor<4>,
        iterations: usize,
        initial: bool,
    ) -> IgevOutput {
        let batch = reference.dims()[0];
        let images = Tensor::cat(vec![reference, target], 0) * 2.0 - 1.0;
        let features = self.pair_features(images.clone(), batch);
        let (geometry, init) = self.initial_estimate(&features);
        let initial = initial.then(|| {
            let x = self.spx_2.forward(
                self.spx_4.forward(features.left[0].clone()),
                features.stem_2x.clone(),
            );
            let weights = softmax(self.spx[0].forward(x), 1);
            context_upsample(init.clone() * 4.0, weights)
        });
        let image1 = images.narrow(0, 0, batch);
        IgevOutput {
            initial,
            iterations: self.refine(image1, features, geometry, init, iterations),
        }
    }

    /// The features of the `batch` pairs stacked in `images` (references
    /// first) that the later stages use.
    fn pair_features(&self, images: Tensor<4>, batch: usize) -> PairFeatures {
        let [f4, f8, f16, f32] = self.feature.forward(images.clone());
        let stem_2 = self.stem_2.forward(images);
        let stem_4 = self.stem_4.forward(stem_2.clone());
        let f4 = Tensor::cat(vec![f4, stem_4], 1);
        let (matching_left, matching_right) =
            halves(self.desc.convolve(self.conv.forward(f4.clone())), batch);
        let left = |x: Tensor<4>| x.narrow(0, 0, batch);
        PairFeatures {
            matching_left,
            matching_right,
            left: [left(f4), left(f8), left(f16), left(f32)],
            stem_2x: left(stem_2),
        }
    }

    /// The geometry encoding volume and the initial disparity regressed
    /// from it (quarter resolution).
    fn initial_estimate(&self, features: &PairFeatures) -> (Tensor<5>, Tensor<4>) {
        let volume = group_correlation_volume(
            features.matching_left.clone(),
            features.matching_right.clone(),
            self.candidates,
            GROUPS,
        );
        let volume = self.corr_stem.forward(volume);
        let volume = self
            .corr_feature_att
            .forward(volume, features.left[0].clone());
        let geometry = self.cost_agg.forward(volume, &features.left);
        let logits = self.classifier.convolve(geometry.clone());
        let [b, _, d, h, w] = logits.dims();
        let init = regress_disparity(logits.reshape([b, d, h, w]));
        (geometry, init)
    }

    /// The full-resolution disparity after each of `iterations` updates of
    /// `init` by the recurrent block, with the context of the references
    /// `image1`.
    fn refine(
        &self,
        image1: Tensor<4>,
        features: PairFeatures,
        geometry: Tensor<5>,
        init: Tensor<4>,
        iterations: usize,
    ) -> Vec<Tensor<4>> {
        let PairFeatures {
            matching_left,
            matching_right,
            stem_2x,
            ..
        } = features;
        let mut state = GruState::from_context(
            self.cnet.forward(image1, self.gru_levels),
            &self.context_zqr_convs,
        );
        let encoding = GeoEncoding::new(
            matching_left,
            matching_right,
            geometry,
            self.corr_levels,
            self.corr_radius,
        );
        let which = LevelsToUpdate {
            coarsest: self.gru_levels == 3,
            middle: self.gru_levels >= 2,
            finest: true,
        };
        let mut disparity = init;
        let mut outputs = Vec::with_capacity(iterations);
        for _ in 0..iterations {
            disparity = disparity.detach();
            let lookup = encoding.lookup(disparity.clone());
            let (features, delta) =
                self.update_block
                    .update(&mut state, which, disparity.clone(), lookup);
            disparity = disparity + delta;
            let x = self.spx_2_gru.forward(features, stem_2x.clone());
            let weights = softmax(self.spx_gru[0].forward(x), 1);
            outputs.push(context_upsample(disparity.clone() * 4.0, weights));
        }
        outputs
    }
}

/// The features of a batch of pairs that the stages after the feature
/// network use.
struct PairFeatures {
    /// The references' matching descriptors (quarter resolution).
    matching_left: Tensor<4>,
    /// The targets' matching descriptors.
    matching_right: Tensor<4>,
    /// The references' features at 1/4, 1/8, 1/16 and 1/32 resolution.
    left: [Tensor<4>; 4],
    /// The references' half-resolution stem.
    stem_2x: Tensor<4>,
}

impl Backbone for IgevStereo {
    fn disparity(&self, reference: Tensor<4>, target: Tensor<4>) -> Tensor<4> {
        let (reference, target, crop) = pad_to_multiple(reference, target, 32);
        let mut out = self.iterate(reference, target, self.test_iters, false);
        crop(
            out.iterations
                .pop()
                .expect("at least one iteration (validated)"),
        )
    }

    fn disparities(&self, reference: Tensor<4>, target: Tensor<4>) -> Vec<Tensor<4>> {
        let (reference, target, crop) = pad_to_multiple(reference, target, 32);
        let out = self.iterate(reference, target, self.train_iters, true);
        out.initial
            .into_iter()
            .chain(out.iterations)
            .map(crop)
            .collect()
    }

    /// The initial disparity regressed from the geometry encoding volume.
    fn initial_estimates(&self) -> usize {
        1
    }
}

impl OfficialLayout for IgevStereo {
    /// The burn paths differ from the official keys where Rust names
    /// `nn.Sequential` members and enum variants: RAFT-Stereo's renaming of
    /// the shared context encoder (whose heads the official IGEV-Stereo
    /// calls `outputs04`, `outputs08`, `outputs16`), no `Plain`/`Transposed`
    /// level, a feature attention's `reduce`/`excite` as `feat_att.0`/`.1`,
    /// and a stem's `conv_in`/`conv` as `0`/`1`.
    fn official_key(path: &str) -> String {
        let raft = RaftStereo::official_key(path);
        let segments: Vec<&str> = raft
            .split('.')
            .filter(|s| !matches!(*s, "Plain" | "Transposed"))
            .collect();
        let mut out = Vec::with_capacity(segments.len() + 1);
        for (i, &segment) in segments.iter().enumerate() {
            let parent = if i >= 1 { segments[i - 1] } else { "" };
            let in_cnet = segments[0] == "cnet";
            match (segment, parent) {
                ("outputs08", "cnet") if in_cnet => out.push("outputs04"),
                ("outputs16", "cnet") if in_cnet => out.push("outputs08"),
                ("outputs32", "cnet") if in_cnet => out.push("outputs16"),
                ("reduce", _) => out.extend(["feat_att", "0"]),
                ("excite", _) => out.extend(["feat_att", "1"]),
                ("conv_in", "stem_2" | "stem_4" | "spx_4") => out.push("0"),
                ("conv", "stem_2" | "stem_4" | "spx_4") => out.push("1"),
                _ => out.push(segment),
            }
        }
        out.join(".")
    }
}

#[cfg(test)]
mod tests;
