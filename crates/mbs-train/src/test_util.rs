//! Helpers shared by the unit tests: tensors from slices and back.

use burn::tensor::{Device, Tensor, TensorData};

/// A `[B, C, H, W]` tensor from row-major values.
pub fn tensor4(data: &[f32], shape: [usize; 4], device: &Device) -> Tensor<4> {
    Tensor::from_data(TensorData::new(data.to_vec(), shape), device)
}

/// The values of a tensor, row-major.
pub fn values<const D: usize>(tensor: Tensor<D>) -> Vec<f32> {
    tensor
        .into_data()
        .try_to_vec::<f32>()
        .expect("test tensors are f32")
}

/// Element-wise `|got - want| <= tolerance`, with the first offender named.
pub fn assert_close(got: &[f32], want: &[f32], tolerance: f32) {
    assert_eq!(got.len(), want.len(), "lengths differ");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= tolerance,
            "element {i}: got {g}, want {w} (tolerance {tolerance})"
        );
    }
}

/// Every float parameter of a module, flattened in visiting order.
#[derive(Default)]
pub struct FlatParams(pub Vec<f32>);

impl burn::module::ModuleVisitor for FlatParams {
    fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<Tensor<D>>) {
        self.0.extend(values(param.val().without_autodiff()));
    }
}
