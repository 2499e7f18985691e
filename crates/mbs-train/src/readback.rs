//! Reading tensors back to the host, with an error naming what was read.

use burn::tensor::Tensor;

use crate::error::TrainError;

/// The first value of `tensor` as f32.
pub(crate) fn read_scalar(tensor: Tensor<1>, what: &'static str) -> Result<f32, TrainError> {
    read_all(tensor, what)?
        .first()
        .copied()
        .ok_or(TrainError::Readback(what))
}

/// Every value of `tensor` as f32, row-major.
pub(crate) fn read_all<const D: usize>(
    tensor: Tensor<D>,
    what: &'static str,
) -> Result<Vec<f32>, TrainError> {
    tensor
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|_| TrainError::Readback(what))
}
