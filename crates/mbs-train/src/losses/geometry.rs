//! Geometry-consistency term `mean(A * |d_s - r d_t|)` (paper eq. 5 with the
//! weight map of eq. 6).

use burn::tensor::{Tensor, TensorData};

/// Weighted L1 between the student disparity and the rescaled teacher
/// disparity, `mean(weights * |student - r * teacher|)`, with one ratio `r`
/// per batch item (`ratios.len() == B`). With a `cap`, pixels whose target
/// `r * teacher` exceeds it weigh 0. The teacher disparity is detached: no
/// gradient reaches the teacher. All maps are `[B, 1, H, W]`.
pub fn geometry_consistency(
    student: Tensor<4>,
    teacher: Tensor<4>,
    ratios: &[f64],
    weights: Tensor<4>,
    cap: Option<f64>,
) -> Tensor<1> {
    let batch = ratios.len();
    let device = student.device();
    let ratios: Vec<f32> = ratios.iter().map(|&r| r as f32).collect();
    let ratios =
        Tensor::<1>::from_data(TensorData::new(ratios, [batch]), &device).reshape([batch, 1, 1, 1]);
    let target = teacher.detach() * ratios;
    let weights = match cap {
        Some(cap) => weights * target.clone().lower_equal_elem(cap).float(),
        None => weights,
    };
    (weights * (student - target).abs()).mean()
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;
    use mbs_nets::test_util::{tensor4, values};

    #[test]
    fn per_sample_ratio_and_weights() {
        let device = Device::flex();
        // Two samples of 1x2 pixels.
        let student = tensor4(&[4.0, 6.0, 1.0, 1.0], [2, 1, 1, 2], &device);
        let teacher = tensor4(&[1.0, 2.0, 2.0, 4.0], [2, 1, 1, 2], &device);
        let weights = tensor4(&[1.0, 2.0, 0.0, 1.0], [2, 1, 1, 2], &device);
        // r = 2 then 0.5: residuals |4-2|, |6-4|, |1-1|, |1-2| = 2, 2, 0, 1;
        // weighted 2, 4, 0, 1 -> mean 7/4.
        let got = geometry_consistency(
            student.clone(),
            teacher.clone(),
            &[2.0, 0.5],
            weights.clone(),
            None,
        );
        assert!((values(got.reshape([1, 1, 1, 1]))[0] - 1.75).abs() < 1e-6);
        // A cap of 3 drops item 0's target 4 (weighted 4), none of item 1's (1, 2): 3/4.
        let got = geometry_consistency(student, teacher, &[2.0, 0.5], weights, Some(3.0));
        assert!((values(got.reshape([1, 1, 1, 1]))[0] - 0.75).abs() < 1e-6);
    }
}
