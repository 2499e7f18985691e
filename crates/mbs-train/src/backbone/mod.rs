//! Stereo backbones: anything that maps a rectified pair to a
//! full-resolution disparity can be trained with S3 (SPEC §5).

pub mod cost_volume;
pub mod igev_stereo;
mod layers;
pub mod network;
pub mod norm;
pub mod official;
pub mod raft_stereo;
pub mod seeded;
pub mod upsample;
#[cfg(all(test, feature = "vulkan"))]
mod vulkan_tests;

use burn::module::Module;
use burn::tensor::Tensor;
use mbs_core::geometry::Side;

use crate::mirror::mirror_left;

pub use cost_volume::{CostVolumeNet, CostVolumeNetConfig};
pub use igev_stereo::{IgevStereo, IgevStereoConfig};
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
