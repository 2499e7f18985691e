//! Stereo networks on burn: the compact cost-volume network, RAFT-Stereo and IGEV-Stereo, their configurations, official weights in and out, devices, host conversion, and inference on whole images as a `StereoMatcher`; usable without the trainer.
//!
//! Any network that maps a rectified pair to a full-resolution disparity
//! ([`Backbone`]) can be trained with S3 (`mbs-train`, conventions §5) and
//! served to `predict`, `eval` and `extrapolate` ([`inference`]).
//!
//! Everything runs on burn's run-time selected device (`Device::flex()` on
//! the CPU, Vulkan or CUDA through [`device::open_device`]).

pub mod checkpoint;
pub mod cost_volume;
pub mod cpu_conv;
pub mod device;
pub mod error;
pub mod host;
pub mod igev_stereo;
pub mod inference;
mod layers;
pub mod mirror;
pub mod network;
pub mod norm;
pub mod official;
pub mod raft_stereo;
pub mod ranges;
pub mod seeded;
#[cfg(any(test, feature = "test-support"))]
pub mod test_util;
pub mod upsample;
#[cfg(all(test, feature = "vulkan"))]
mod vulkan_tests;

use burn::module::Module;
use burn::tensor::Tensor;
use mbs_core::geometry::Side;

use crate::mirror::mirror_left;

pub use cost_volume::{CostVolumeNet, CostVolumeNetConfig};
pub use error::NetError;
pub use igev_stereo::{IgevStereo, IgevStereoConfig};
pub use inference::NetworkMatcher;
pub use network::{BackboneKind, NetworkConfig, StereoNetwork};
pub use raft_stereo::{RaftStereo, RaftStereoConfig};

/// A stereo network for a target on the **right** of the reference.
pub trait Backbone: Module {
    /// Disparity `[B, 1, H, W]` (pixels, >= 0, on the reference grid) for
    /// reference and target images `[B, 3, H, W]` in `[0, 1]`.
    fn disparity(&self, reference: Tensor<4>, target: Tensor<4>) -> Tensor<4>;

    /// The training-time predictions, coarsest iteration first and the
    /// final one last (iterative networks return one per update; others
    /// their single [`Backbone::disparity`]).
    fn disparities(&self, reference: Tensor<4>, target: Tensor<4>) -> Vec<Tensor<4>> {
        vec![self.disparity(reference, target)]
    }

    /// How many of [`Backbone::disparities`]' predictions, first, are
    /// direct estimates made before the iterative updates
    /// (IGEV-Stereo's initial disparity: 1), which training weighs apart
    /// from the updates' sequence; 0 for the others.
    fn initial_estimates(&self) -> usize {
        0
    }
}

/// Disparity for pairs whose targets lie on either side: left-side items
/// are mirrored in, predicted as right-side pairs, and mirrored back.
///
/// # Panics
/// When `sides.len()` differs from the batch size.
pub fn predict<B: Backbone>(
    backbone: &B,
    reference: Tensor<4>,
    target: Tensor<4>,
    sides: &[Side],
) -> Tensor<4> {
    let reference = mirror_left(reference, sides);
    let target = mirror_left(target, sides);
    mirror_left(backbone.disparity(reference, target), sides)
}

/// Every training-time prediction ([`Backbone::disparities`]) for pairs
/// whose targets lie on either side, as [`predict`].
///
/// # Panics
/// When `sides.len()` differs from the batch size.
pub fn predict_sequence<B: Backbone>(
    backbone: &B,
    reference: Tensor<4>,
    target: Tensor<4>,
    sides: &[Side],
) -> Vec<Tensor<4>> {
    let reference = mirror_left(reference, sides);
    let target = mirror_left(target, sides);
    backbone
        .disparities(reference, target)
        .into_iter()
        .map(|d| mirror_left(d, sides))
        .collect()
}
