//! Tests of the assembled S3 loss on a hand-computed 2x4 case.
//!
//! With `alpha = 0` and a 1x1 SSIM window the photometric map is the plain
//! L1 error, so every number below follows by hand. Both rows are equal.
//! - Reference `I_r = [0, 0.2, 0.4, 0.6]`.
//! - Student target (right) `[0.2, 0.45, 0.6, 0.8]`, `d_s = [1, 1, 1, 2]`:
//!   warped `[0.2, 0.2, 0.45, 0.45]`, `P_s = [0.2, 0, 0.05, 0.15]`,
//!   identity `[0.2, 0.25, 0.2, 0.2]`, `M_s = [0, 1, 1, 0]`.
//! - Teacher target (right) `[0.4, 0.6, 0.8, 1.0]`, `d_t = 2`: warped
//!   `[0.4, 0.4, 0.4, 0.6]`, `P_t = [0.4, 0.2, 0, 0]`, identity 0.4,
//!   `M_t = [0, 0, 1, 1]`; `A = [0, 0, 1, omega = 2]`.
//! - `r = 0.5`: `|d_s - r d_t| = [0, 0, 0, 1]`, `L_g = 2 / 4 = 0.5`;
//!   `mean(M_s P_s) = 0.05 / 4 = 0.0125`;
//!   `L_s = exp(-0.2) / 3` (one disparity step of 1 across an image step of 0.2);
//!   `L = 0.5 + 10 * 0.0125 + 0.01 * exp(-0.2) / 3`.

use super::*;
use burn::tensor::Device;
use mbs_nets::NetError;
use mbs_nets::test_util::{assert_close, tensor4, values};

fn rows(row: [f32; 4]) -> Vec<f32> {
    [row, row].concat()
}

fn inputs(device: &Device) -> LossInputs {
    let shape = [1, 1, 2, 4];
    LossInputs {
        geometry_weight: 1.0,
        reference: tensor4(&rows([0.0, 0.2, 0.4, 0.6]), shape, device),
        student_target: tensor4(&rows([0.2, 0.45, 0.6, 0.8]), shape, device),
        teacher_target: tensor4(&rows([0.4, 0.6, 0.8, 1.0]), shape, device),
        student_disparity: tensor4(&rows([1.0, 1.0, 1.0, 2.0]), shape, device),
        teacher_disparity: tensor4(&rows([2.0; 4]), shape, device),
        student_sides: vec![Side::Right],
        teacher_sides: vec![Side::Right],
        ratios: vec![0.5],
    }
}

/// L1 photometric error and the paper's geometry term, for hand values.
fn l1_config() -> LossConfig {
    LossConfig::new()
        .with_alpha(0.0)
        .with_ssim_window(1)
        .with_geometry_scale_match(false)
}

fn scalar(tensor: Option<Tensor<1>>) -> f32 {
    values(tensor.expect("term is on"))[0]
}

#[test]
fn defaults_are_the_papers() {
    let config = LossConfig::new();
    assert_eq!(
        (config.tau, config.omega, config.lambda_p, config.alpha),
        (0.1, 2.0, 10.0, 0.85)
    );
    assert!((config.lambda_s() - 0.01).abs() < 1e-12);
    assert_eq!(config.ssim_window, 7);
    assert!(config.validate().is_ok());
}

#[test]
fn hand_computed_total_and_parts() {
    let device = Device::flex();
    let loss = S3Loss::new(l1_config()).expect("valid config");
    let out = loss.compute(inputs(&device)).expect("shapes match");
    assert_close(
        &values(out.student_mask.clone().expect("on")),
        &rows([0.0, 1.0, 1.0, 0.0]),
        0.0,
    );
    assert_close(
        &values(out.teacher_mask.clone().expect("on")),
        &rows([0.0, 0.0, 1.0, 1.0]),
        0.0,
    );
    assert_close(
        &values(out.weight_map.clone().expect("on")),
        &rows([0.0, 0.0, 1.0, 2.0]),
        0.0,
    );
    assert!((scalar(out.term(Term::Geometry)) - 0.5).abs() < 1e-6);
    assert!((scalar(out.term(Term::Photometric)) - 0.0125).abs() < 1e-6);
    let smooth = (-0.2f32).exp() / 3.0;
    assert!((scalar(out.term(Term::Smoothness)) - smooth).abs() < 1e-6);
    let total = values(out.total)[0];
    assert!(
        (total - (0.5 + 0.125 + 0.01 * smooth)).abs() < 1e-6,
        "{total}"
    );
}

#[test]
fn ablation_switches() {
    let device = Device::flex();
    let compute = |config: LossConfig| {
        S3Loss::new(config)
            .expect("valid config")
            .compute(inputs(&device))
            .expect("shapes match")
    };
    // OAE off: A = [0, 0, 1, 1], L_g = 1/4.
    let out = compute(l1_config().with_occlusion_enhancement(false));
    assert!((scalar(out.term(Term::Geometry)) - 0.25).abs() < 1e-6);
    // PTF off: M_s = [0, 1, 1, 1], M_t = [0, 1, 1, 1], L_g = 1/4, L_p = 0.2/4.
    let out = compute(l1_config().with_threshold_filter(false));
    assert!((scalar(out.term(Term::Geometry)) - 0.25).abs() < 1e-6);
    assert!((scalar(out.term(Term::Photometric)) - 0.05).abs() < 1e-6);
    // Table 3 (A): no geometry term, so no teacher mask and no weight map.
    let out = compute(l1_config().with_geometry(false));
    assert!(
        out.term(Term::Geometry).is_none()
            && out.weight_map.is_none()
            && out.teacher_mask.is_none()
    );
    let smooth = (-0.2f32).exp() / 3.0;
    assert!((values(out.total)[0] - (0.125 + 0.01 * smooth)).abs() < 1e-6);
    // The photometric term over M_s = [0, 1, 1, 0] only: 0.05 / 2.
    let out = compute(l1_config().with_photometric_mask_mean(true));
    assert!((scalar(out.term(Term::Photometric)) - 0.025).abs() < 1e-6);
    // Table 3 (B): geometry + photometric only.
    let out = compute(l1_config().with_smoothness(false));
    assert!(out.term(Term::Smoothness).is_none());
    assert!((values(out.total)[0] - 0.625).abs() < 1e-6);
}

#[test]
fn gradient_reaches_the_student_only() {
    let device = Device::flex().autodiff();
    let mut batch = inputs(&device);
    batch.student_disparity = batch.student_disparity.require_grad();
    batch.teacher_disparity = batch.teacher_disparity.require_grad();
    let student = batch.student_disparity.clone();
    let teacher = batch.teacher_disparity.clone();
    let out = S3Loss::new(l1_config())
        .expect("valid")
        .compute(batch)
        .expect("shapes match");
    let grads = out.total.backward();
    let grad = values(student.grad(&grads).expect("student gradient"));
    assert!(grad.iter().all(|g| g.is_finite()));
    // Pixel (0, 3): the geometry term alone gives A / N = 2 / 8.
    assert!(grad[3] > 0.2, "{grad:?}");
    assert!(teacher.grad(&grads).is_none());
}

#[test]
fn rejects_bad_settings_and_shapes() {
    assert!(matches!(
        S3Loss::new(LossConfig::new().with_ssim_window(4)),
        Err(TrainError::Network(NetError::InvalidSetting {
            name: "ssim_window",
            ..
        }))
    ));
    assert!(S3Loss::new(LossConfig::new().with_alpha(1.5)).is_err());
    let all_off = LossConfig::new()
        .with_geometry(false)
        .with_photometric(false)
        .with_smoothness(false);
    assert!(S3Loss::new(all_off).is_err());
    let device = Device::flex();
    let mut batch = inputs(&device);
    batch.ratios = vec![0.5, 0.5];
    assert!(matches!(
        S3Loss::new(l1_config()).expect("valid").compute(batch),
        Err(TrainError::Shape(_))
    ));
    // The default 7x7 window does not fit a 2-row image.
    assert!(
        S3Loss::new(LossConfig::new())
            .expect("valid")
            .compute(inputs(&device))
            .is_err()
    );
}

#[test]
fn a_sequence_adds_each_earlier_prediction_weighted() {
    let device = Device::flex();
    let loss = S3Loss::new(l1_config()).expect("valid");
    let shape = [1, 1, 2, 4];
    // An earlier prediction of 2 px everywhere, scored on its own too.
    let earlier = tensor4(&rows([2.0; 4]), shape, &device);
    let alone = loss
        .compute(LossInputs {
            student_disparity: earlier.clone(),
            ..inputs(&device)
        })
        .expect("valid");
    let last = loss.compute(inputs(&device)).expect("valid");
    let sequence = loss
        .compute_sequence(inputs(&device), vec![(earlier, 0.25)])
        .expect("valid");
    let total = |out: &LossOutput| values(out.total.clone())[0];
    assert!((total(&sequence) - (total(&last) + 0.25 * total(&alone))).abs() < 1e-6);
    assert!(
        total(&alone) > 0.1,
        "the earlier prediction has a loss of its own"
    );
    // The reported terms are the final prediction's.
    assert_eq!(
        scalar(sequence.term(Term::Geometry)),
        scalar(last.term(Term::Geometry))
    );
    // An earlier prediction of another shape is refused.
    let wrong = Tensor::<4>::zeros([1, 1, 2, 3], &device);
    assert!(
        loss.compute_sequence(inputs(&device), vec![(wrong, 1.0)])
            .is_err()
    );
}

#[test]
fn a_collapsed_prediction_is_pulled_back_by_the_range_term_only() {
    // Teacher and student at -200 px: every warp reads the target's border,
    // which matches worse than no warp, so both masks are empty; the
    // paper's terms then give no gradient at all (the smoothness of a flat
    // map is zero too), and only the range term leads back.
    let device = Device::flex().autodiff();
    let gradient = |range_weight: f64| {
        let mut batch = inputs(&device);
        batch.student_disparity = Tensor::full([1, 1, 2, 4], -200.0, &device).require_grad();
        batch.teacher_disparity = Tensor::full([1, 1, 2, 4], -200.0, &device);
        let student = batch.student_disparity.clone();
        let out = S3Loss::new(l1_config().with_range_weight(range_weight))
            .expect("valid")
            .compute(batch)
            .expect("shapes match");
        assert_close(&values(out.student_mask.expect("on")), &[0.0; 8], 0.0);
        assert_close(&values(out.teacher_mask.expect("on")), &[0.0; 8], 0.0);
        values(
            student
                .grad(&out.total.backward())
                .expect("student requires grad"),
        )
    };
    assert_close(&gradient(0.0), &[0.0; 8], 0.0);
    // d(mean(-d))/dd = -1/8 per pixel: gradient descent raises every pixel.
    assert_close(&gradient(1.0), &[-0.125; 8], 1e-6);
}

#[test]
fn a_warp_that_leaves_the_target_is_no_match() {
    // Teacher target [0.15, 0.1, 0.8, 1.0] with d_t = 2: pixel 1 samples
    // column -1, clamped to the border 0.15, which is within tau of the
    // reference 0.2 and beats its identity error 0.1; the paper's tests
    // accept it. Pixels 2 and 3 land inside and fail (0.25, 0.5 > tau).
    let device = Device::flex();
    let teacher_mask = |out_of_view_invalid: bool| {
        let mut batch = inputs(&device);
        batch.teacher_target = tensor4(&rows([0.15, 0.1, 0.8, 1.0]), [1, 1, 2, 4], &device);
        let out = S3Loss::new(l1_config().with_out_of_view_invalid(out_of_view_invalid))
            .expect("valid")
            .compute(batch)
            .expect("shapes match");
        values(out.teacher_mask.expect("on"))
    };
    assert_close(&teacher_mask(false), &rows([0.0, 1.0, 0.0, 0.0]), 0.0);
    assert_close(&teacher_mask(true), &rows([0.0; 4]), 0.0);
}

#[test]
fn a_pixel_outside_the_students_mask_keeps_a_photometric_gradient() {
    // Pixel 3 (P_s = 0.15 > tau) is outside M_s. Its warp samples column
    // 1 exactly, between 0.45 and 0.6: dP_s/dd_s = 0.15. With only the
    // photometric term, the paper's M_s P_s gives it no gradient; a weight
    // beta outside the mask gives lambda_p beta 0.15 / 8.
    let device = Device::flex().autodiff();
    let run = |beta: f64| {
        let mut batch = inputs(&device);
        batch.student_disparity = batch.student_disparity.require_grad();
        let student = batch.student_disparity.clone();
        let config = l1_config()
            .with_geometry(false)
            .with_smoothness(false)
            .with_outside_mask_weight(beta);
        let out = S3Loss::new(config)
            .expect("valid")
            .compute(batch)
            .expect("shapes match");
        let photometric = scalar(out.term(Term::Photometric));
        let grad = values(
            student
                .grad(&out.total.backward())
                .expect("student gradient"),
        );
        (photometric, grad)
    };
    let (paper, paper_grad) = run(0.0);
    assert!((paper - 0.0125).abs() < 1e-6);
    assert_eq!(paper_grad[3], 0.0);
    // Weights [0.5, 1, 1, 0.5] on P_s = [0.2, 0, 0.05, 0.15]: 0.225 / 4.
    let (kept, kept_grad) = run(0.5);
    assert!((kept - 0.05625).abs() < 1e-6, "{kept}");
    assert!(
        (kept_grad[3] - 10.0 * 0.5 * 0.15 / 8.0).abs() < 1e-5,
        "{kept_grad:?}"
    );
    // Pixel 0's warp leaves the target (clamped): no gradient either way.
    assert_eq!(kept_grad[0], 0.0);
    assert!(S3Loss::new(l1_config().with_outside_mask_weight(1.5)).is_err());
}

#[test]
fn a_warp_past_the_targets_edge_is_pulled_back_by_the_view_term_only() {
    // d_s = 2.5 everywhere on a 4-pixel row: inside the range [0, 3], so
    // the range term is zero, but pixels 0-2 sample columns -2.5, -1.5,
    // -0.5 of the target on the right, read its clamped border and have no
    // photometric gradient. The view term ((2.5 + 1.5 + 0.5) per row over
    // 4 pixels) lowers them.
    let device = Device::flex().autodiff();
    let run = |view_weight: f64| {
        let mut batch = inputs(&device);
        batch.student_disparity = Tensor::full([1, 1, 2, 4], 2.5, &device).require_grad();
        let student = batch.student_disparity.clone();
        let config = l1_config()
            .with_geometry(false)
            .with_smoothness(false)
            .with_view_weight(view_weight);
        let out = S3Loss::new(config)
            .expect("valid")
            .compute(batch)
            .expect("shapes match");
        assert_eq!(scalar(out.term(Term::Range)), 0.0);
        let view = out.term(Term::View).map(|v| values(v)[0]);
        let grad = values(
            student
                .grad(&out.total.backward())
                .expect("student gradient"),
        );
        (view, grad)
    };
    let (paper, paper_grad) = run(0.0);
    assert_eq!(paper, None);
    assert_close(&paper_grad[..3], &[0.0; 3], 0.0);
    let (view, grad) = run(1.0);
    assert_close(&[view.expect("on")], &[1.125], 1e-6);
    // Gradient descent lowers each overshooting disparity, 1/8 per pixel.
    assert_close(&grad[..3], &[0.125; 3], 1e-6);
    assert_close(&grad[4..7], &[0.125; 3], 1e-6);
    assert!(S3Loss::new(l1_config().with_view_weight(-1.0)).is_err());
}
