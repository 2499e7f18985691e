//! Validity masks `M = (P < tau) AND (P < P_identity)` and the
//! occlusion-aware weight map `A` (paper eq. 6).

use burn::tensor::Tensor;

/// Which parts of the validity mask are switched on (paper Table 4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaskParts {
    /// Photometric threshold filtering (PTF): keep `P < tau`, or `None` to skip.
    pub threshold: Option<f64>,
    /// Auto-masking filtering (AMF): keep `P < P_identity`.
    pub auto_mask: bool,
}

/// Validity mask as a 0/1 float map `[B, 1, H, W]` (no gradient): 1 where
/// the warped error beats the threshold and the identity error, for the
/// parts switched on; all ones when both are off.
pub fn validity_mask(photometric: Tensor<4>, identity: Tensor<4>, parts: MaskParts) -> Tensor<4> {
    let photometric = photometric.detach();
    let mut mask = photometric.ones_like();
    if let Some(tau) = parts.threshold {
        mask = mask * photometric.clone().lower_elem(tau).float();
    }
    if parts.auto_mask {
        mask = mask * photometric.lower(identity.detach()).float();
    }
    mask
}

/// Occlusion-aware weight map from the teacher and student masks (0/1
/// maps): 1 where both are valid, 0 where the teacher is not, `omega`
/// where the teacher is valid and the student is not. `omega = 1` switches
/// occlusion-aware enhancement (OAE) off.
pub fn weight_map(teacher_mask: Tensor<4>, student_mask: Tensor<4>, omega: f64) -> Tensor<4> {
    // M_t * (M_s + omega (1 - M_s))
    teacher_mask * (student_mask.clone() * (1.0 - omega) + omega)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;
    use mbs_nets::test_util::{assert_close, tensor4, values};

    fn maps() -> (Tensor<4>, Tensor<4>) {
        let device = Device::flex();
        // P:        0.05  0.05  0.20  0.05
        // identity: 0.10  0.01  0.30  0.05
        (
            tensor4(&[0.05, 0.05, 0.2, 0.05], [1, 1, 1, 4], &device),
            tensor4(&[0.1, 0.01, 0.3, 0.05], [1, 1, 1, 4], &device),
        )
    }

    #[test]
    fn mask_parts_switch_independently() {
        let (p, id) = maps();
        let both = MaskParts {
            threshold: Some(0.1),
            auto_mask: true,
        };
        assert_close(
            &values(validity_mask(p.clone(), id.clone(), both)),
            &[1.0, 0.0, 0.0, 0.0],
            0.0,
        );
        let threshold_only = MaskParts {
            threshold: Some(0.1),
            auto_mask: false,
        };
        assert_close(
            &values(validity_mask(p.clone(), id.clone(), threshold_only)),
            &[1.0, 1.0, 0.0, 1.0],
            0.0,
        );
        // Strict inequality: a tie with the identity error is masked out.
        let auto_only = MaskParts {
            threshold: None,
            auto_mask: true,
        };
        assert_close(
            &values(validity_mask(p.clone(), id.clone(), auto_only)),
            &[1.0, 0.0, 1.0, 0.0],
            0.0,
        );
        let none = MaskParts {
            threshold: None,
            auto_mask: false,
        };
        assert_close(&values(validity_mask(p, id, none)), &[1.0; 4], 0.0);
    }

    #[test]
    fn weight_map_covers_the_three_regions() {
        let device = Device::flex();
        // (M_t, M_s) = (1,1), (1,0), (0,1), (0,0).
        let teacher = tensor4(&[1.0, 1.0, 0.0, 0.0], [1, 1, 1, 4], &device);
        let student = tensor4(&[1.0, 0.0, 1.0, 0.0], [1, 1, 1, 4], &device);
        let a = weight_map(teacher.clone(), student.clone(), 2.0);
        assert_close(&values(a), &[1.0, 2.0, 0.0, 0.0], 0.0);
        let without_enhancement = weight_map(teacher, student, 1.0);
        assert_close(&values(without_enhancement), &[1.0, 1.0, 0.0, 0.0], 0.0);
    }
}
