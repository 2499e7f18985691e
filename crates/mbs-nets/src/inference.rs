//! A trained backbone on whole images: `RgbImage` pair in, disparity map
//! on the reference grid out (targets on the left go through mirroring);
//! a checkpoint's teacher, or a backbone with weights from a file (an
//! official checkpoint, an export), as a `StereoMatcher` for `predict`,
//! `eval` and `extrapolate`.

use std::path::Path;

use burn::tensor::Device;
use mbs_core::{FloatImage, MaskImage, RgbImage, Side};
use mbs_infer::{Disparity, InferError, StereoMatcher};

use crate::checkpoint::TrainedNetworks;
use crate::error::NetError;
use crate::host::{image_tensor, read_all};
use crate::{Backbone, NetworkConfig, StereoNetwork, predict};

/// Disparity of `reference` (pixels, on its grid) against `target`, which
/// lies on `side` of it. The images must have the same size.
pub fn predict_image<B: Backbone>(
    net: &B,
    reference: &RgbImage,
    target: &RgbImage,
    side: Side,
    device: &Device,
) -> Result<FloatImage, NetError> {
    if reference.dimensions() != target.dimensions() {
        return Err(NetError::Shape(format!(
            "reference is {:?} but target is {:?} (width, height)",
            reference.dimensions(),
            target.dimensions()
        )));
    }
    let (width, height) = reference.dimensions();
    let disparity = predict(
        net,
        image_tensor(reference, device),
        image_tensor(target, device),
        &[side],
    );
    let values = read_all(disparity, "the disparity")?;
    FloatImage::from_raw(width, height, values)
        .ok_or_else(|| NetError::Shape("the network returned a map of the wrong size".into()))
}

/// A trained network as a [`StereoMatcher`] on a device: what `predict`
/// and `eval` run with `--checkpoint` or `--weights`.
pub struct NetworkMatcher {
    net: StereoNetwork,
    device: Device,
    name: String,
}

impl NetworkMatcher {
    /// The network of `config` with the weights of `path` (an official
    /// `.pth`/`.safetensors` state dict or an `mbs-tool export`), on `device`.
    pub fn with_weights(
        config: &NetworkConfig,
        path: &Path,
        device: Device,
    ) -> Result<Self, NetError> {
        let net = config.init(&device)?.with_weights(path)?;
        Ok(Self {
            net,
            device,
            name: format!("{} ({})", config.backbone, path.display()),
        })
    }

    /// Loads the teacher of a checkpoint folder, or of the newest
    /// checkpoint of a training run folder, on `device`.
    pub fn open(path: &Path, device: Device) -> Result<Self, NetError> {
        let checkpoint = TrainedNetworks::open(path)?;
        let net = checkpoint.teacher(&device)?;
        Ok(Self {
            net,
            device,
            name: format!(
                "S3 teacher ({}, step {})",
                checkpoint.dir.display(),
                checkpoint.steps
            ),
        })
    }
}

impl StereoMatcher for NetworkMatcher {
    fn name(&self) -> &str {
        &self.name
    }

    fn predict(&self, left: &RgbImage, right: &RgbImage) -> Result<Disparity, InferError> {
        let disparity = predict_image(&self.net, left, right, Side::Right, &self.device)
            .map_err(|e| InferError::Backend(e.to_string()))?;
        mbs_infer::matcher::check_values(self.name(), &disparity)?;
        let valid =
            MaskImage::from_pixel(disparity.width(), disparity.height(), image::Luma([255]));
        Ok(Disparity { disparity, valid })
    }
}
