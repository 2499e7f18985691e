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
