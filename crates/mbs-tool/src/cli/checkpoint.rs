//! `--checkpoint`: the teacher of a training run as a [`StereoMatcher`].

use std::path::Path;

use anyhow::Context;
use burn::tensor::Device;
use mbs_core::{RgbImage, Side};
use mbs_infer::{Disparity, StereoMatcher};
use mbs_train::CostVolumeNet;
use mbs_train::checkpoint::Checkpoint;
use mbs_train::inference::predict_image;

/// The teacher network of a checkpoint, on the CPU.
pub struct CheckpointMatcher {
    net: CostVolumeNet,
    device: Device,
    name: String,
}

impl CheckpointMatcher {
    /// Loads the teacher of a checkpoint folder, or of the newest
    /// checkpoint of a training run folder.
    pub fn open(path: &Path) -> anyhow::Result<Self> {
        let checkpoint = Checkpoint::open(path)?;
        let device = Device::flex();
        let net = checkpoint
            .teacher(&device)
            .with_context(|| format!("loading the teacher of {}", checkpoint.dir.display()))?;
        Ok(Self {
            net,
            device,
            name: format!(
                "S3 teacher ({}, step {})",
                checkpoint.dir.display(),
                checkpoint.state.steps
            ),
        })
    }
}

impl StereoMatcher for CheckpointMatcher {
    fn name(&self) -> &str {
        &self.name
    }

    fn predict(
        &self,
        left: &RgbImage,
        right: &RgbImage,
    ) -> Result<Disparity, mbs_infer::InferError> {
        let disparity = predict_image(&self.net, left, right, Side::Right, &self.device)
            .map_err(|e| mbs_infer::InferError::Backend(e.to_string()))?;
        let valid =
            image::GrayImage::from_pixel(disparity.width(), disparity.height(), image::Luma([255]));
        Ok(Disparity { disparity, valid })
    }
}
