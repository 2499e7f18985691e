//! Geometry-consistency term `mean(A * |d_s - r d_t|)` (paper eq. 5 with the
//! weight map of eq. 6).

use burn::tensor::{Tensor, TensorData};
use mbs_nets::host::read_all;

/// How the geometry target `r d_t` is rescaled to the student's scale
/// before the comparison (`trainer.loss.geometry_scale_match` and
/// `trainer.loss.geometry_scale_neutral`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScaleMatch {
    /// The paper's term: no rescaling.
    Off,
    /// Equal weighted means ([`match_scale`]).
    Mean,
    /// The scale at which the L1 term has no net pull on the student's
    /// scale ([`match_scale_neutral`]).
    Neutral,
}

/// Weighted L1 between the student disparity and the rescaled teacher
/// disparity, `mean(weights * |student - r * teacher|)`, with one ratio `r`
/// per batch item (`ratios.len() == B`). With a `cap`, pixels whose target
/// `r * teacher` exceeds it weigh 0. With `scale_match`, each item's
/// target is first rescaled to the student's scale ([`ScaleMatch`]). The teacher disparity is detached: no gradient reaches
/// the teacher. All maps are `[B, 1, H, W]`.
pub fn geometry_consistency(
    student: Tensor<4>,
    teacher: Tensor<4>,
    ratios: &[f64],
    weights: Tensor<4>,
    cap: Option<f64>,
    scale_match: ScaleMatch,
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
        ScaleMatch::Off => target,
        ScaleMatch::Mean => match_scale(target, student.clone(), weights.clone()),
        ScaleMatch::Neutral => match_scale_neutral(target, student.clone(), weights.clone()),
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

/// `target` times the factor `c` per batch item (no gradient) at which
/// the weighted L1 term exerts no net pull on the student's scale: its
/// derivative along `d_s -> s d_s`, `sum(w d_s sign(d_s - c t))`, vanishes
/// when `c` is the median of the ratios `d_s / t` weighted by `w d_s`.
/// Equal means ([`match_scale`]) leave a pull whenever the two maps'
/// distributions differ in shape: an L1 term pulls toward medians, and a
/// teacher whose range is narrower than the student's shrinks the
/// student's scale step after step (docs/quality.md, "S3 from random
/// weights: the drift toward small disparities"). Pixels with a
/// non-positive student or target disparity do not vote; an item with no
/// voting pixel keeps the mean match.
pub fn match_scale_neutral(target: Tensor<4>, student: Tensor<4>, weights: Tensor<4>) -> Tensor<4> {
    let [batch, channels, height, width] = target.dims();
    let fallback = match_scale(target.clone(), student.clone(), weights.clone());
    let read = |map: Tensor<4>| read_all(map.detach(), "geometry scale");
    let (Ok(t), Ok(d), Ok(w), Ok(f)) = (
        read(target.clone()),
        read(student),
        read(weights),
        read(fallback.clone()),
    ) else {
        return fallback;
    };
    let per_item = channels * height * width;
    let factors: Vec<f32> = (0..batch)
        .map(|b| {
            let range = b * per_item..(b + 1) * per_item;
            let votes = range
                .clone()
                .filter(|&i| w[i] > 0.0 && d[i] > 0.0 && t[i] > 0.0)
                .map(|i| (d[i] / t[i], w[i] * d[i]));
            weighted_median(votes.collect())
                .unwrap_or_else(|| mean_factor(&t[range.clone()], &f[range]))
        })
        .collect();
    let device = target.device();
    let factors = Tensor::<1>::from_data(TensorData::new(factors, [batch]), &device);
    target * factors.reshape([batch, 1, 1, 1])
}

/// The factor the mean match applied to an item (`matched / target` where
/// the target is not zero; 1 otherwise).
fn mean_factor(target: &[f32], matched: &[f32]) -> f32 {
    target
        .iter()
        .zip(matched)
        .find(|(t, _)| t.abs() > 1e-6)
        .map_or(1.0, |(t, m)| m / t)
}

/// The weighted median of `(value, weight)` pairs: the smallest value at
/// which the cumulative weight reaches half the total; `None` when the
/// total weight is not positive.
pub fn weighted_median(mut votes: Vec<(f32, f32)>) -> Option<f32> {
    let total: f64 = votes.iter().map(|(_, w)| f64::from(*w)).sum();
    if total <= 0.0 {
        return None;
    }
    votes.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut cumulative = 0.0;
    votes
        .into_iter()
        .find(|(_, w)| {
            cumulative += f64::from(*w);
            cumulative >= total / 2.0
        })
        .map(|(value, _)| value)
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
            ScaleMatch::Off,
        );
        assert!((values(got.reshape([1, 1, 1, 1]))[0] - 1.75).abs() < 1e-6);
        // A cap of 3 drops item 0's target 4 (weighted 4), none of item 1's (1, 2): 3/4.
        let got = geometry_consistency(
            student,
            teacher,
            &[2.0, 0.5],
            weights,
            Some(3.0),
            ScaleMatch::Off,
        );
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

    #[test]
    fn the_neutral_match_leaves_no_pull_on_the_scale() {
        let device = Device::flex();
        // One item, student 1, 2, 10 (weights 1), target 2, 2, 2: ratios
        // 0.5, 1, 5 weighted 1, 2, 10 -> median 5 (cumulative 1, 3, 13 >= 6.5).
        let target = tensor4(&[2.0, 2.0, 2.0], [1, 1, 1, 3], &device);
        let student = tensor4(&[1.0, 2.0, 10.0], [1, 1, 1, 3], &device);
        let weights = tensor4(&[1.0, 1.0, 1.0], [1, 1, 1, 3], &device);
        let matched = values(match_scale_neutral(target, student, weights));
        assert!(
            matched.iter().all(|v| (v - 10.0).abs() < 1e-5),
            "{matched:?}"
        );
        assert_eq!(
            weighted_median(vec![(3.0, 1.0), (1.0, 1.0), (2.0, 1.0)]),
            Some(2.0)
        );
        assert_eq!(weighted_median(vec![(3.0, 0.0)]), None);
    }
}
