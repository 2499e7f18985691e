//! Global gradient-norm clipping, as PyTorch's `clip_grad_norm_` (which
//! IGEV-Stereo and RAFT-Stereo use with 1.0): all gradients are scaled by
//! `min(1, max_norm / (||g|| + 1e-6))`, `||g||` over every parameter at once.
//! (burn's own `GradientClipping::Norm` clips each parameter separately.)

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::GradientsParams;
use burn::tensor::Tensor;

use crate::error::TrainError;
use mbs_nets::host::read_scalar;

/// Sums the squared gradients of a module's float parameters (on the device).
struct SquaredNorm<'a> {
    grads: &'a GradientsParams,
    total: Option<Tensor<1>>,
}

impl ModuleVisitor for SquaredNorm<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(grad) = self.grads.get::<D>(param.id) {
            let squares = (grad.clone() * grad).sum();
            self.total = Some(match self.total.take() {
                Some(total) => total + squares,
                None => squares,
            });
        }
    }
}

/// Multiplies every gradient of a module's float parameters by `factor`.
struct Scale<'a> {
    grads: &'a mut GradientsParams,
    factor: f64,
}

impl ModuleVisitor for Scale<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(grad) = self.grads.remove::<D>(param.id) {
            self.grads.register(param.id, grad * self.factor);
        }
    }
}

/// Scales `grads` (of `module`'s parameters) so their global L2 norm is at
/// most `max_norm`; returns the norm before clipping.
pub fn clip_global_norm<M: Module>(
    module: &M,
    grads: &mut GradientsParams,
    max_norm: f64,
) -> Result<f64, TrainError> {
    unscale_and_clip(module, grads, max_norm, 1.0)
}

/// Divides `grads`, the gradients of a loss multiplied by `loss_scale`
/// (see [`crate::precision::LossScale`]), by that scale and clips them as
/// [`clip_global_norm`]; returns the unscaled norm before clipping, which
/// is not finite when a gradient overflowed (the gradients are then left
/// as they are).
pub fn unscale_and_clip<M: Module>(
    module: &M,
    grads: &mut GradientsParams,
    max_norm: f64,
    loss_scale: f64,
) -> Result<f64, TrainError> {
    let mut norm = SquaredNorm { grads, total: None };
    module.visit(&mut norm);
    let Some(squares) = norm.total else {
        return Ok(0.0);
    };
    let squares = read_scalar(squares, "the gradient norm")?;
    let total = f64::from(squares).sqrt() / loss_scale;
    if !total.is_finite() {
        return Ok(total);
    }
    let factor = (max_norm / (total + 1e-6)).min(1.0) / loss_scale;
    if factor != 1.0 {
        module.visit(&mut Scale { grads, factor });
    }
    Ok(total)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::{Linear, LinearConfig};
    use burn::tensor::{Device, TensorData};
    use mbs_nets::test_util::{assert_close, values};

    /// A 2x2 linear layer with weight gradient [[1, 2], [2, 0]] and bias
    /// gradient [0, 4]: global norm sqrt(1 + 4 + 4 + 16) = 5.
    fn setup() -> (Linear, GradientsParams) {
        let device = Device::flex().autodiff();
        let layer = LinearConfig::new(2, 2).init(&device);
        let mut grads = GradientsParams::new();
        let weight = Tensor::<2>::from_data(
            TensorData::new(vec![1.0f32, 2.0, 2.0, 0.0], [2, 2]),
            &device.clone().inner(),
        );
        let bias = Tensor::<1>::from_data(TensorData::new(vec![0.0f32, 4.0], [2]), &device.inner());
        grads.register(layer.weight.id, weight);
        grads.register(layer.bias.as_ref().expect("bias on").id, bias);
        (layer, grads)
    }

    #[test]
    fn scales_all_gradients_by_one_factor() {
        let (layer, mut grads) = setup();
        let norm = clip_global_norm(&layer, &mut grads, 1.0).expect("readable");
        assert!((norm - 5.0).abs() < 1e-6);
        let weight = grads.get::<2>(layer.weight.id).expect("kept");
        assert_close(&values(weight), &[0.2, 0.4, 0.4, 0.0], 1e-6);
        let bias = grads
            .get::<1>(layer.bias.expect("bias on").id)
            .expect("kept");
        assert_close(&values(bias), &[0.0, 0.8], 1e-6);
    }

    #[test]
    fn leaves_small_gradients_alone() {
        let (layer, mut grads) = setup();
        let norm = clip_global_norm(&layer, &mut grads, 10.0).expect("readable");
        assert!((norm - 5.0).abs() < 1e-6);
        let weight = grads.get::<2>(layer.weight.id).expect("kept");
        assert_close(&values(weight), &[1.0, 2.0, 2.0, 0.0], 0.0);
    }

    #[test]
    fn unscales_before_measuring_and_clipping() {
        let (layer, mut grads) = setup();
        // The gradients of a loss scaled by 4: the true norm is 5 / 4.
        let norm = unscale_and_clip(&layer, &mut grads, 10.0, 4.0).expect("readable");
        assert!((norm - 1.25).abs() < 1e-6);
        let weight = grads.get::<2>(layer.weight.id).expect("kept");
        assert_close(&values(weight), &[0.25, 0.5, 0.5, 0.0], 1e-6);

        let (layer, mut grads) = setup();
        let norm = unscale_and_clip(&layer, &mut grads, 0.5, 4.0).expect("readable");
        assert!((norm - 1.25).abs() < 1e-6);
        let bias = grads
            .get::<1>(layer.bias.expect("bias on").id)
            .expect("kept");
        // Unscaled [0, 1], then clipped from 1.25 to 0.5.
        assert_close(&values(bias), &[0.0, 0.4], 1e-6);
    }

    #[test]
    fn reports_an_overflow_as_a_norm_that_is_not_finite() {
        let (layer, mut grads) = setup();
        let device = Device::flex();
        let overflow =
            Tensor::<1>::from_data(TensorData::new(vec![f32::INFINITY, 4.0], [2]), &device);
        let bias_id = layer.bias.as_ref().expect("bias on").id;
        grads.remove::<1>(bias_id);
        grads.register(bias_id, overflow);
        let norm = unscale_and_clip(&layer, &mut grads, 1.0, 1024.0).expect("readable");
        assert!(norm.is_infinite());
        let weight = grads.get::<2>(layer.weight.id).expect("kept");
        assert_close(&values(weight), &[1.0, 2.0, 2.0, 0.0], 0.0);
    }
}
