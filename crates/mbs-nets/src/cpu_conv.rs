//! The networks' 2-D and 3-D convolutions: on the CPU (burn's flex device,
//! f32, with or without autodiff) `mbs-conv`'s kernels, whose backward is
//! written here for burn's autodiff (input and weight gradients from
//! `mbs-conv`, the bias's from burn); on any other device or format
//! (Vulkan, CUDA, f16, bf16) burn's own convolution. Every network calls
//! [`Convolve::convolve`] instead of burn's `Conv2d::forward` and
//! `Conv3d::forward` (clippy's `disallowed-methods` keeps it so).
//!
//! burn's flex backend has no backward convolution of its own: its
//! generic fallback computes the weight gradient as a convolution whose
//! kernel is the whole output map and loops over groups, several times
//! slower than PyTorch (BENCHMARKS.md, "Convolutions one layer at a time").

use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::NoCheckpointing;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::flex::FlexTensor;
use burn::backend::{
    Autodiff, BackendTensor, DispatchAutodiffContext, DispatchTensor, DispatchTensorKind, Flex,
    GradientCheckpointingStrategy,
};
use burn::module::Param;
use burn::nn::PaddingConfig2d;
use burn::nn::PaddingConfig3d;
use burn::nn::conv::{Conv2d, Conv3d};
use burn::tensor::{DType, Tensor, TensorData};
use mbs_conv::Conv;

/// A convolution layer the networks run through [`cpu_conv`](self).
pub trait Convolve<const D: usize> {
    /// The layer's output for `input`: what burn's `forward` computes.
    fn convolve(&self, input: Tensor<D>) -> Tensor<D>;
}

impl Convolve<4> for Conv2d {
    fn convolve(&self, input: Tensor<4>) -> Tensor<4> {
        let padding = match self.padding {
            PaddingConfig2d::Valid => [[0, 0]; 2],
            PaddingConfig2d::Explicit(top, left, bottom, right) => [[top, bottom], [left, right]],
            #[allow(clippy::disallowed_methods)] // `Same` padding: burn computes it
            PaddingConfig2d::Same => return self.forward(input),
        };
        let [batch, in_channels, height, width] = input.dims();
        let geometry = Conv {
            batch,
            in_channels,
            out_channels: self.weight.dims()[0],
            groups: self.groups,
            input: [1, height, width],
            kernel: [1, self.kernel_size[0], self.kernel_size[1]],
            stride: [1, self.stride[0], self.stride[1]],
            padding: [[0, 0], padding[0], padding[1]],
            dilation: [1, self.dilation[0], self.dilation[1]],
        };
        #[allow(clippy::disallowed_methods)] // burn's own, off the CPU
        layer_output(geometry, input, &self.weight, &self.bias, |x| {
            self.forward(x)
        })
    }
}

impl Convolve<5> for Conv3d {
    fn convolve(&self, input: Tensor<5>) -> Tensor<5> {
        let padding = match self.padding {
            PaddingConfig3d::Valid => [0; 3],
            PaddingConfig3d::Explicit(depth, height, width) => [depth, height, width],
            #[allow(clippy::disallowed_methods)] // `Same` padding: burn computes it
            PaddingConfig3d::Same => return self.forward(input),
        };
        let [batch, in_channels, depth, height, width] = input.dims();
        let geometry = Conv {
            batch,
            in_channels,
            out_channels: self.weight.dims()[0],
            groups: self.groups,
            input: [depth, height, width],
            kernel: self.kernel_size,
            stride: self.stride,
            padding: padding.map(|p| [p, p]),
            dilation: self.dilation,
        };
        #[allow(clippy::disallowed_methods)] // burn's own, off the CPU
        layer_output(geometry, input, &self.weight, &self.bias, |x| {
            self.forward(x)
        })
    }
}

/// A layer's output for `input`: its convolution by `geometry` with
/// `weight`, plus `bias` per output channel, by `mbs-conv` when input and
/// weights are f32 on the CPU, else `burn_forward(input)`.
fn layer_output<const D: usize>(
    geometry: Conv,
    input: Tensor<D>,
    weight: &Param<Tensor<D>>,
    bias: &Option<Param<Tensor<1>>>,
    burn_forward: impl FnOnce(Tensor<D>) -> Tensor<D>,
) -> Tensor<D> {
    let convolved = match convolve(geometry, input, weight.val()) {
        Ok(output) => output,
        Err(input) => return burn_forward(input),
    };
    match bias {
        Some(bias) => {
            let mut channels = [1; D];
            channels[1] = -1;
            convolved + bias.val().reshape(channels)
        }
        None => convolved,
    }
}

/// Where a tensor lives, as far as this module cares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Route {
    /// burn's flex CPU backend, no autodiff.
    Flex,
    /// burn's flex CPU backend under autodiff without checkpointing.
    AutodiffFlex,
}

fn route(tensor: &DispatchTensor) -> Option<Route> {
    match (&tensor.kind, tensor.autodiff) {
        (DispatchTensorKind::Flex(BackendTensor::Float(_)), DispatchAutodiffContext::Disabled) => {
            Some(Route::Flex)
        }
        (
            DispatchTensorKind::Autodiff(inner),
            DispatchAutodiffContext::Enabled(GradientCheckpointingStrategy::Disabled),
        ) if matches!(
            **inner,
            DispatchTensorKind::Flex(BackendTensor::Autodiff(_))
        ) =>
        {
            Some(Route::AutodiffFlex)
        }
        _ => None,
    }
}

/// The convolution of `input` with `weight` by `mbs-conv` when both are
/// f32 on the CPU; otherwise the input back, for burn's own convolution.
#[allow(clippy::result_large_err)] // the error hands the input back
fn convolve<const D: usize>(
    geometry: Conv,
    input: Tensor<D>,
    weight: Tensor<D>,
) -> Result<Tensor<D>, Tensor<D>> {
    let f32s = input.dtype() == DType::F32 && weight.dtype() == DType::F32;
    if !f32s || geometry.check().is_err() {
        return Err(input);
    }
    let (input, weight) = (input.into_dispatch(), weight.into_dispatch());
    let both = route(&input).filter(|r| Some(*r) == route(&weight));
    let primitive = |tensor: DispatchTensor| Tensor::<D>::from_dispatch(tensor);
    match both {
        Some(Route::Flex) => {
            let (x, w) = match (
                primitive(input).try_into_primitive::<Flex>(),
                primitive(weight).try_into_primitive::<Flex>(),
            ) {
                (Ok(x), Ok(w)) => (x, w),
                _ => unreachable!("routed to flex, so both are flex tensors"),
            };
            Ok(Tensor::from_primitive::<Flex>(forward(&geometry, &x, &w)))
        }
        Some(Route::AutodiffFlex) => {
            let (x, w) = match (
                primitive(input).try_into_primitive::<Autodiff<Flex>>(),
                primitive(weight).try_into_primitive::<Autodiff<Flex>>(),
            ) {
                (Ok(x), Ok(w)) => (x, w),
                _ => unreachable!("routed to autodiff flex, so both are autodiff flex tensors"),
            };
            let ((x, x_node), (w, w_node)) = (x.into_parts(), w.into_parts());
            let output = forward(&geometry, &x, &w);
            let output = match ConvBackward
                .prepare::<NoCheckpointing>([x_node, w_node])
                .compute_bound()
                .stateful()
            {
                OpsKind::Tracked(prepared) => prepared.finish((x, w, geometry), output),
                OpsKind::UnTracked(prepared) => prepared.finish(output),
            };
            Ok(Tensor::from_primitive::<Autodiff<Flex>>(output))
        }
        None => Err(primitive(input)),
    }
}

/// The values of a flex f32 tensor, row-major (copied only when its
/// layout is not contiguous).
fn values(tensor: &FlexTensor) -> std::borrow::Cow<'_, [f32]> {
    match tensor.as_slice::<f32>() {
        Some(values) => values.into(),
        None => tensor
            .to_contiguous()
            .as_slice::<f32>()
            .map(<[f32]>::to_vec)
            .unwrap_or_default()
            .into(),
    }
}

/// A flex tensor of `shape` holding `values` (taken, not copied).
fn flex(values: Vec<f32>, shape: Vec<usize>) -> FlexTensor {
    FlexTensor::from_data(TensorData::new(values, shape))
}

fn shape(tensor: &FlexTensor) -> Vec<usize> {
    tensor.layout().shape().to_vec()
}

fn forward(geometry: &Conv, input: &FlexTensor, weight: &FlexTensor) -> FlexTensor {
    let output = geometry.forward(&values(input), &values(weight));
    let [depth, height, width] = geometry.output();
    let mut dims = vec![geometry.batch, geometry.out_channels];
    match shape(input).len() {
        4 => dims.extend([height, width]),
        _ => dims.extend([depth, height, width]),
    }
    flex(output, dims)
}

/// The backward of [`convolve`]: input and weight gradients by `mbs-conv`.
#[derive(Debug)]
struct ConvBackward;

impl Backward<Flex, 2> for ConvBackward {
    type State = (FlexTensor, FlexTensor, Conv);

    fn backward(self, ops: Ops<Self::State, 2>, grads: &mut Gradients, _: &mut Checkpointer) {
        let [input_node, weight_node] = ops.parents;
        let output_gradient = grads.consume::<Flex>(&ops.node);
        let (input, weight, geometry) = ops.state;
        let dy = values(&output_gradient);
        if let Some(node) = input_node {
            let gradient = geometry.input_gradient(&values(&weight), &dy);
            grads.register::<Flex>(node.id, flex(gradient, shape(&input)));
        }
        if let Some(node) = weight_node {
            let gradient = geometry.weight_gradient(&values(&input), &dy);
            grads.register::<Flex>(node.id, flex(gradient, shape(&weight)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::module::{Module, Param};
    use burn::nn::conv::{Conv2dConfig, Conv3dConfig};
    use burn::tensor::{Device, Distribution};

    use crate::test_util::values;

    /// A convolution of the networks: channels in and out, kernel side,
    /// stride, padding, dilation, groups.
    type Case = ([usize; 2], usize, usize, usize, usize, usize);

    /// The 2-D shapes of the compact network, RAFT-Stereo (encoders, motion
    /// encoder, ConvGRUs, flow and mask heads) and IGEV-Stereo (MobileNetV2
    /// features with their depthwise convolutions, stems, descriptors,
    /// context upsampling), with their real channel counts.
    const CASES_2D: [Case; 16] = [
        ([3, 64], 7, 2, 3, 1, 1),      // RAFT-Stereo encoder stem
        ([64, 64], 3, 1, 1, 1, 1),     // residual block
        ([64, 96], 3, 2, 1, 1, 1),     // residual block, down
        ([64, 96], 1, 2, 0, 1, 1),     // its projection
        ([128, 256], 1, 1, 0, 1, 1),   // encoder output
        ([36, 64], 1, 1, 0, 1, 1),     // motion encoder, correlation
        ([2, 64], 7, 1, 3, 1, 1),      // motion encoder, flow
        ([192, 128], 3, 1, 1, 1, 1),   // ConvGRU gate
        ([128, 576], 1, 1, 0, 1, 1),   // mask head
        ([256, 2], 3, 1, 1, 1, 1),     // flow head
        ([3, 32], 3, 2, 1, 1, 1),      // IGEV-Stereo stem
        ([96, 96], 3, 2, 1, 1, 96),    // MobileNetV2 depthwise, down
        ([144, 144], 3, 1, 1, 1, 144), // MobileNetV2 depthwise
        ([8, 16], 3, 1, 1, 1, 8),      // depthwise with a multiplier of 2
        ([24, 24], 3, 1, 2, 2, 1),     // dilated
        ([16, 24], 3, 1, 1, 1, 2),     // grouped
    ];

    /// The 3-D shapes of IGEV-Stereo's cost-volume hourglass.
    const CASES_3D: [Case; 4] = [
        ([8, 16], 3, 1, 1, 1, 1),  // corr_stem
        ([16, 32], 3, 2, 1, 1, 1), // down
        ([32, 32], 3, 1, 1, 1, 1), // agg
        ([32, 8], 1, 1, 0, 1, 1),  // 1x1x1
    ];

    /// The output, input gradient and parameter gradients of `run` on
    /// `input`, for the loss `sum(output * seeds)`.
    fn outcome<const D: usize>(
        run: impl Fn(Tensor<D>) -> Tensor<D>,
        input: &Tensor<D>,
        seeds: &Tensor<D>,
        parameters: (&Param<Tensor<D>>, Option<&Param<Tensor<1>>>),
    ) -> [Vec<f32>; 4] {
        let input = input.clone().require_grad();
        let output = run(input.clone());
        let grads = (output.clone() * seeds.clone()).sum().backward();
        let grad = |g: Option<Tensor<D>>| g.map(values).unwrap_or_default();
        [
            values(output),
            grad(input.grad(&grads)),
            grad(parameters.0.grad(&grads)),
            parameters
                .1
                .and_then(|b| b.grad(&grads))
                .map(values)
                .unwrap_or_default(),
        ]
    }

    fn assert_agree(what: String, ours: [Vec<f32>; 4], burns: [Vec<f32>; 4]) {
        for (part, (a, b)) in [
            "output",
            "input gradient",
            "weight gradient",
            "bias gradient",
        ]
        .iter()
        .zip(ours.iter().zip(&burns))
        {
            assert_eq!(a.len(), b.len(), "{what}: {part} sizes");
            assert!(!a.is_empty(), "{what}: no {part}");
            let scale = b.iter().fold(1.0f32, |m, v| m.max(v.abs()));
            let worst = a
                .iter()
                .zip(b)
                .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
            assert!(
                worst <= 1e-4 * scale,
                "{what}: {part} differs by {worst} (largest value {scale})"
            );
        }
    }

    /// Every convolution shape of the networks, at odd sizes and batch 1
    /// and 2, with and without autodiff: mbs-conv's output and its input,
    /// weight and bias gradients agree with burn's own within 1e-4 of the
    /// largest value (float sums in another order).
    #[test]
    fn every_network_shape_agrees_with_burn_in_value_and_gradients() {
        let device = Device::flex().autodiff();
        device.seed(5);
        // One seed for all cases, drawn in this order.
        for batch in [1, 2] {
            for case in CASES_2D {
                check_2d_case(&device, batch, case);
            }
            for case in CASES_3D {
                check_3d_case(&device, batch, case);
            }
        }
    }

    /// One 2-D case of [`every_network_shape_agrees_with_burn_in_value_and_gradients`]:
    /// the tensors take mbs-conv's path, and agree with burn's with and
    /// without autodiff.
    #[allow(clippy::disallowed_methods)] // burn's own is the reference
    fn check_2d_case(device: &Device, batch: usize, case: Case) {
        let ([from, to], kernel, stride, padding, dilation, groups) = case;
        let layer = Conv2dConfig::new([from, to], [kernel, kernel])
            .with_stride([stride, stride])
            .with_padding(PaddingConfig2d::Explicit(
                padding, padding, padding, padding,
            ))
            .with_dilation([dilation, dilation])
            .with_groups(groups)
            .init(device);
        let input = Tensor::<4>::random([batch, from, 11, 13], Distribution::Default, device);
        let output_shape = layer.forward(input.clone()).dims();
        let seeds = Tensor::<4>::random(output_shape, Distribution::Default, device);
        let parameters = (&layer.weight, layer.bias.as_ref());
        // The networks' tensors take mbs-conv's path, with and without autodiff.
        let routed = |t: Tensor<4>| route(&t.into_dispatch());
        assert_eq!(
            routed(input.clone().require_grad()),
            Some(Route::AutodiffFlex)
        );
        assert_eq!(routed(layer.weight.val()), Some(Route::AutodiffFlex));
        assert_eq!(routed(input.clone().inner()), Some(Route::Flex));
        let ours = outcome(|x| layer.convolve(x), &input, &seeds, parameters);
        let burns = outcome(|x| layer.forward(x), &input, &seeds, parameters);
        let what = format!(
            "2-D {from}->{to} k{kernel} s{stride} p{padding} d{dilation} g{groups} b{batch}"
        );
        assert_agree(what, ours, burns);
        // Without autodiff (inference, the teacher).
        let plain = layer.valid();
        let x = input.clone().inner();
        let (a, b) = (values(plain.convolve(x.clone())), values(plain.forward(x)));
        assert_eq!(a.len(), b.len());
        assert!(
            a.iter()
                .zip(&b)
                .all(|(x, y)| (x - y).abs() <= 1e-4 * (1.0 + y.abs()))
        );
    }

    /// One 3-D case of [`every_network_shape_agrees_with_burn_in_value_and_gradients`].
    #[allow(clippy::disallowed_methods)] // burn's own is the reference
    fn check_3d_case(device: &Device, batch: usize, case: Case) {
        let ([from, to], kernel, stride, padding, dilation, groups) = case;
        let layer = Conv3dConfig::new([from, to], [kernel; 3])
            .with_stride([stride; 3])
            .with_padding(PaddingConfig3d::Explicit(padding, padding, padding))
            .with_dilation([dilation; 3])
            .with_groups(groups)
            .init(device);
        let input = Tensor::<5>::random([batch, from, 5, 7, 9], Distribution::Default, device);
        let output_shape = layer.forward(input.clone()).dims();
        let seeds = Tensor::<5>::random(output_shape, Distribution::Default, device);
        let parameters = (&layer.weight, layer.bias.as_ref());
        let ours = outcome(|x| layer.convolve(x), &input, &seeds, parameters);
        let burns = outcome(|x| layer.forward(x), &input, &seeds, parameters);
        let what = format!("3-D {from}->{to} k{kernel} s{stride} p{padding} b{batch}");
        assert_agree(what, ours, burns);
    }
}
