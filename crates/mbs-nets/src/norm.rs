//! The normalisation layers of the official stereo networks, with PyTorch's
//! parameter names (`weight`, `bias`, `running_mean`, `running_var`) so
//! their state dicts map one to one.
//!
//! Batch normalisation is frozen: it always uses the running statistics, as
//! the official RAFT-Stereo and IGEV-Stereo training does (`freeze_bn`);
//! its affine parameters still train.

use burn::module::{Module, Param};
use burn::tensor::{Device, Tensor};
use serde::{Deserialize, Serialize};

/// PyTorch's default `eps` of its normalisation layers.
const EPS: f64 = 1e-5;

/// Which normalisation a layer applies (the official `norm_fn`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NormKind {
    /// `nn.BatchNorm2d`, frozen (running statistics).
    Batch,
    /// `nn.InstanceNorm2d` without affine parameters.
    Instance,
    /// `nn.GroupNorm` with `channels / 8` groups.
    Group,
    /// No normalisation.
    None,
}

/// One normalisation layer over `[B, C, H, W]`.
#[derive(Module, Debug)]
pub struct Norm {
    weight: Option<Param<Tensor<1>>>,
    bias: Option<Param<Tensor<1>>>,
    running_mean: Option<Param<Tensor<1>>>,
    running_var: Option<Param<Tensor<1>>>,
    /// Groups of a group norm; 0 otherwise.
    groups: usize,
    instance: bool,
}

impl Norm {
    /// A fresh layer over `channels` channels (`groups` for a group norm).
    pub fn new(kind: NormKind, channels: usize, groups: usize, device: &Device) -> Self {
        let ones = || Param::from_tensor(Tensor::ones([channels], device));
        let zeros = || Param::from_tensor(Tensor::zeros([channels], device));
        let constant = |p: Param<Tensor<1>>| p.set_require_grad(false);
        let affine = matches!(kind, NormKind::Batch | NormKind::Group);
        Norm {
            weight: affine.then(ones),
            bias: affine.then(zeros),
            running_mean: (kind == NormKind::Batch).then(|| constant(zeros())),
            running_var: (kind == NormKind::Batch).then(|| constant(ones())),
            groups: if kind == NormKind::Group { groups } else { 0 },
            instance: kind == NormKind::Instance,
        }
    }

    /// Normalises `x` (`[B, C, H, W]`).
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let channel = |p: &Param<Tensor<1>>| p.val().reshape([1, -1, 1, 1]);
        let x = if let (Some(mean), Some(var)) = (&self.running_mean, &self.running_var) {
            (x - channel(mean)) / (channel(var) + EPS).sqrt()
        } else if self.instance {
            instance_normalise(x)
        } else if self.groups > 0 {
            let [b, c, h, w] = x.dims();
            let grouped = x.reshape([b, self.groups, c / self.groups * h * w]);
            let (var, mean) = grouped.clone().var_mean_bias(2);
            ((grouped - mean) / (var + EPS).sqrt()).reshape([b, c, h, w])
        } else {
            x
        };
        match (&self.weight, &self.bias) {
            (Some(weight), Some(bias)) => x * channel(weight) + channel(bias),
            _ => x,
        }
    }
}

/// `(x - mean) / sqrt(var + eps)` over each `[H, W]` plane (biased variance).
fn instance_normalise(x: Tensor<4>) -> Tensor<4> {
    let [b, c, h, w] = x.dims();
    let flat = x.reshape([b, c, h * w]);
    let (var, mean) = flat.clone().var_mean_bias(2);
    ((flat - mean) / (var + EPS).sqrt()).reshape([b, c, h, w])
}
