//! Mixed precision: the networks compute in bf16 or f16 while the weights,
//! the optimiser state and the losses stay in f32.
//!
//! burn has no autocast, so each step casts the f32 ("master") weights of
//! both networks to the compute format ([`cast_network`]); on an autodiff
//! device the cast is recorded, so the gradients reach the master weights
//! and arrive in f32. The images are cast on their way into a network and
//! its predictions back to f32 on their way out, so the S3 loss (SSIM,
//! warps, masks) runs in f32 as under PyTorch's autocast.
//!
//! f16's narrow range makes small gradients underflow, so an f16 run scales
//! its loss ([`LossScale`], as PyTorch's `GradScaler`); bf16 has f32's
//! range and needs no scaling.

use std::fmt;

use burn::module::{Module, ModuleMapper, Param};
use burn::tensor::{Device, FloatDType, Tensor};
use serde::{Deserialize, Serialize};

use crate::error::TrainError;
use mbs_nets::NetError;

/// The format the networks compute in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// Everything in f32.
    #[default]
    F32,
    /// Networks in bfloat16 (f32's range, 8 bits of mantissa).
    Bf16,
    /// Networks in IEEE half precision, with a dynamic loss scale.
    F16,
}

impl Precision {
    /// The networks' format, or `None` for f32 (nothing is cast).
    pub fn compute_dtype(self) -> Option<FloatDType> {
        match self {
            Self::F32 => None,
            Self::Bf16 => Some(FloatDType::BF16),
            Self::F16 => Some(FloatDType::F16),
        }
    }
}

impl std::str::FromStr for Precision {
    type Err = TrainError;

    fn from_str(text: &str) -> Result<Self, TrainError> {
        match text {
            "f32" => Ok(Self::F32),
            "bf16" => Ok(Self::Bf16),
            "f16" => Ok(Self::F16),
            other => Err(TrainError::Config(format!(
                "unknown precision `{other}`; expected f32, bf16 or f16"
            ))),
        }
    }
}

impl fmt::Display for Precision {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::F32 => "f32",
            Self::Bf16 => "bf16",
            Self::F16 => "f16",
        })
    }
}

/// Refuses `precision` when one of `devices`, each with the name the error
/// gives it, cannot compute in its format (bf16 on most Vulkan drivers, f16
/// on some).
pub fn check_support<'a>(
    precision: Precision,
    devices: impl IntoIterator<Item = (String, &'a Device)>,
) -> Result<(), TrainError> {
    let Some(dtype) = precision.compute_dtype() else {
        return Ok(());
    };
    match devices
        .into_iter()
        .find(|(_, device)| !device.supports_dtype(dtype))
    {
        Some((name, _)) => Err(NetError::Device {
            name,
            reason: format!(
                "it cannot compute in {precision} (trainer.precision): use another precision \
                 (f32 always works) or another device"
            ),
        }
        .into()),
        None => Ok(()),
    }
}

/// Casts every float parameter it maps to one format.
struct CastParameters(FloatDType);

impl ModuleMapper for CastParameters {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let dtype = self.0;
        param.map(|tensor| tensor.cast(dtype))
    }
}

/// `network` with every float parameter cast to `dtype`. The parameters
/// keep their ids; on an autodiff device the casts are part of the graph,
/// so a loss's gradients are the original parameters', in their format.
pub fn cast_network<M: Module>(network: M, dtype: FloatDType) -> M {
    network.map(&mut CastParameters(dtype))
}

/// The loss scale of an f16 run, as PyTorch's `GradScaler`: the loss is
/// multiplied by the scale before the backward pass and the gradients
/// divided by it after; a step whose gradients overflow is skipped and
/// halves the scale, and 2000 steps in a row without overflow double it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LossScale {
    /// The current factor.
    pub scale: f64,
    /// Steps since the last overflow or growth.
    pub good_steps: usize,
}

impl LossScale {
    /// PyTorch's initial scale, 2^16 (`trainer.initial_loss_scale`).
    pub const PYTORCH_INITIAL: f64 = 65536.0;

    /// A scale of `scale` with no step taken yet.
    pub fn starting_at(scale: f64) -> Self {
        Self {
            scale,
            good_steps: 0,
        }
    }

    /// Steps without overflow before the scale doubles.
    const GROWTH_INTERVAL: usize = 2000;

    /// Records a step's outcome: `finite` when every gradient was finite
    /// (the step was taken), otherwise it was skipped.
    pub fn update(&mut self, finite: bool) {
        if finite {
            self.good_steps += 1;
            if self.good_steps == Self::GROWTH_INTERVAL {
                self.scale *= 2.0;
                self.good_steps = 0;
            }
        } else {
            self.scale = (self.scale / 2.0).max(1.0);
            self.good_steps = 0;
        }
    }
}

/// f16 steps skipped in a row after which a run counts as diverged: each
/// skip halves the loss scale (down to 1), so by then the gradients
/// overflow at any scale.
pub const MAX_SKIPPED_STEPS: usize = 30;

/// The loss scaling of an f16 run: the [`LossScale`] (what a checkpoint
/// keeps) and the overflowing steps skipped in a row since the last step
/// taken (what tells a diverged run from one still finding its scale).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossScaling {
    scale: LossScale,
    skipped_in_a_row: usize,
}

impl LossScaling {
    /// Scaling from `scale`, with no step skipped yet.
    pub fn starting_at(scale: f64) -> Self {
        Self {
            scale: LossScale::starting_at(scale),
            skipped_in_a_row: 0,
        }
    }

    /// The current scale and its count of good steps.
    pub fn scale(&self) -> LossScale {
        self.scale
    }

    /// Puts back the scale a checkpoint saved.
    pub fn restore(&mut self, saved: LossScale) {
        self.scale = saved;
    }

    /// Records a step whose gradient norm (of the scaled gradients,
    /// unscaled) is `grad_norm`: `Ok(true)` when its gradients overflowed,
    /// so that the step is skipped and the scale halved; an error, saying
    /// what happened, once [`MAX_SKIPPED_STEPS`] steps in a row did.
    pub fn record(&mut self, grad_norm: f64) -> Result<bool, String> {
        let overflowed = !grad_norm.is_finite();
        self.scale.update(!overflowed);
        self.skipped_in_a_row = match overflowed {
            true => self.skipped_in_a_row + 1,
            false => 0,
        };
        if self.skipped_in_a_row >= MAX_SKIPPED_STEPS {
            return Err(format!(
                "the f16 gradients overflowed {MAX_SKIPPED_STEPS} steps in a row \
                 (loss scale now {})",
                self.scale.scale
            ));
        }
        Ok(overflowed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::{Linear, LinearConfig};
    use burn::optim::GradientsParams;
    use burn::tensor::{DType, TensorData};

    #[test]
    fn settings_are_read_and_written_in_lower_case() {
        for (text, precision) in [
            ("\"f32\"", Precision::F32),
            ("\"bf16\"", Precision::Bf16),
            ("\"f16\"", Precision::F16),
        ] {
            assert_eq!(serde_json::from_str::<Precision>(text).unwrap(), precision);
            assert_eq!(serde_json::to_string(&precision).unwrap(), text);
        }
        assert!(serde_json::from_str::<Precision>("\"fp8\"").is_err());
    }

    #[test]
    fn a_cast_network_computes_in_its_format_and_its_gradients_reach_the_f32_weights() {
        let device = Device::flex().autodiff();
        let layer: Linear = LinearConfig::new(3, 2).init(&device);
        let weight = layer.weight.val();
        assert_eq!(weight.dtype(), DType::F32);
        let input = Tensor::<2>::from_data(
            TensorData::new(vec![0.5f32, -1.0, 2.0, 1.5, 0.25, -0.75], [2, 3]),
            &device,
        );
        let exact = layer.forward(input.clone()).sum();
        let exact_grads = GradientsParams::from_grads(exact.clone().backward(), &layer);

        let half = cast_network(layer.clone(), FloatDType::BF16);
        assert_eq!(half.weight.val().dtype(), DType::BF16);
        assert_eq!(half.weight.id, layer.weight.id);
        let output = half.forward(input.cast(FloatDType::BF16));
        assert_eq!(output.dtype(), DType::BF16);
        let total = output.cast(FloatDType::F32).sum();
        let grads = GradientsParams::from_grads(total.clone().backward(), &layer);
        let grad = grads.get::<2>(layer.weight.id).unwrap();
        assert_eq!(grad.dtype(), DType::F32);
        let exact_grad = exact_grads.get::<2>(layer.weight.id).unwrap();
        // bf16 keeps 8 bits of mantissa: about 2 significant digits.
        let difference = (grad - exact_grad).abs().max().into_scalar::<f32>();
        assert!(difference < 2e-2, "weight gradient off by {difference}");
        let loss_difference = (total - exact).abs().into_scalar::<f32>();
        assert!(loss_difference < 5e-2, "output off by {loss_difference}");
    }

    #[test]
    fn the_loss_scale_halves_on_overflow_and_doubles_after_2000_good_steps() {
        let mut scale = LossScale::starting_at(LossScale::PYTORCH_INITIAL);
        scale.update(false);
        assert_eq!(scale.scale, 32768.0);
        for _ in 0..1999 {
            scale.update(true);
        }
        assert_eq!(scale.scale, 32768.0);
        scale.update(true);
        assert_eq!((scale.scale, scale.good_steps), (65536.0, 0));
        let mut tiny = LossScale {
            scale: 1.0,
            good_steps: 7,
        };
        tiny.update(false);
        assert_eq!((tiny.scale, tiny.good_steps), (1.0, 0));
    }

    /// An overflow skips the step; a good step ends the streak; the
    /// streak's limit is an error saying how far the scale fell.
    #[test]
    fn loss_scaling_counts_overflows_in_a_row_and_refuses_at_the_limit() {
        let mut scaling = LossScaling::starting_at(4.0);
        for _ in 0..MAX_SKIPPED_STEPS - 1 {
            assert_eq!(scaling.record(f64::INFINITY), Ok(true));
        }
        assert_eq!(scaling.scale().scale, 1.0, "halved down to 1, no lower");
        assert_eq!(scaling.record(0.5), Ok(false));
        for _ in 0..MAX_SKIPPED_STEPS - 1 {
            assert_eq!(scaling.record(f64::NAN), Ok(true));
        }
        let message = scaling.record(f64::INFINITY).expect_err("the limit");
        assert!(
            message.contains(&format!("overflowed {MAX_SKIPPED_STEPS} steps in a row")),
            "{message}"
        );
        assert!(message.contains("loss scale now 1"), "{message}");
    }

    /// A checkpoint's scale comes back whole (factor and good steps), and
    /// the scale then grows from the saved count of good steps.
    #[test]
    fn restoring_puts_back_the_saved_scale_and_its_good_steps() {
        let mut scaling = LossScaling::starting_at(LossScale::PYTORCH_INITIAL);
        let saved = LossScale {
            scale: 256.0,
            good_steps: 1999,
        };
        scaling.restore(saved);
        assert_eq!(scaling.scale(), saved);
        assert_eq!(scaling.record(1.0), Ok(false));
        assert_eq!(scaling.scale(), LossScale::starting_at(512.0));
    }
}
