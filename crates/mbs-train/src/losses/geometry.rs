//! Geometry-consistency term `mean(A * |d_s - r d_t|)` (paper eq. 5 with the
//! weight map of eq. 6).

use burn::tensor::{Tensor, TensorData};

/// Weighted L1 between the student disparity and the rescaled teacher
/// disparity, `mean(weights * |student - r * teacher|)`, with one ratio `r`
/// per batch item (`ratios.len() == B`). With a `cap`, pixels whose target
/// `r * teacher` exceeds it weigh 0. With `scale_match`, each item's
/// target is first rescaled so that its weighted mean equals the student's
/// ([`match_scale`]). The teacher disparity is detached: no gradient reaches
/// the teacher. All maps are `[B, 1, H, W]`.
pub fn geometry_consistency(
    student: Tensor<4>,
    teacher: Tensor<4>,
    ratios: &[f64],
    weights: Tensor<4>,
    cap: Option<f64>,
    scale_match: bool,
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
    let target = match scale_match {
        true => match_scale(target, student.clone(), weights.clone()),
        false => target,
    };
    (weights * (student - target).abs()).mean()
}

/// `target` times `sum(w d_s) / sum(w target)` per batch item (no
/// gradient): the teacher's target keeps its shape but takes the student's
/// overall scale, so the term cannot change the student's scale, which the
/// photometric term alone then sets. A trained teacher's target already has
/// the student's scale (the factor is near 1); an untrained teacher, which
/// predicts alike on the narrow and the wide pair, would otherwise push the
/// student to `r` times its own disparities step after step. An item with
/// no weight keeps its target.
pub fn match_scale(target: Tensor<4>, student: Tensor<4>, weights: Tensor<4>) -> Tensor<4> {
    let per_item = |map: Tensor<4>| map.sum_dim(3).sum_dim(2).sum_dim(1);
    let student_sum = per_item(weights.clone() * student.detach());
    let target_sum = per_item(weights * target.clone());
    let has_weight = target_sum.clone().abs().greater_elem(1e-6).float();
    let scale = (student_sum / (target_sum.abs().clamp_min(1e-6))) * has_weight.clone()
        + (has_weight.neg() + 1.0);
    target * scale
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
            false,
        );
        assert!((values(got.reshape([1, 1, 1, 1]))[0] - 1.75).abs() < 1e-6);
        // A cap of 3 drops item 0's target 4 (weighted 4), none of item 1's (1, 2): 3/4.
        let got = geometry_consistency(student, teacher, &[2.0, 0.5], weights, Some(3.0), false);
        assert!((values(got.reshape([1, 1, 1, 1]))[0] - 0.75).abs() < 1e-6);
    }

    #[test]
    fn scale_matching_keeps_the_shape_and_takes_the_students_scale() {
        let device = Device::flex();
        // Item 0: target 2, 4 (weights 1, 1), student 3, 3: scale 6/6 = 1.
        // Item 1: target 1, 3 (weights 1, 0), student 5, 9: scale 5/1 = 5.
        let target = tensor4(&[2.0, 4.0, 1.0, 3.0], [2, 1, 1, 2], &device);
        let student = tensor4(&[3.0, 3.0, 5.0, 9.0], [2, 1, 1, 2], &device);
        let weights = tensor4(&[1.0, 1.0, 1.0, 0.0], [2, 1, 1, 2], &device);
        let matched = values(match_scale(target.clone(), student.clone(), weights));
        assert!(
            matched
                .iter()
                .zip([2.0, 4.0, 5.0, 15.0])
                .all(|(a, b)| (a - b).abs() < 1e-5),
            "{matched:?}"
        );
        // No weight at all: the target is kept.
        let none = Tensor::<4>::zeros([2, 1, 1, 2], &device);
        assert_eq!(
            values(match_scale(target, student, none)),
            [2.0, 4.0, 1.0, 3.0]
        );
    }
}
