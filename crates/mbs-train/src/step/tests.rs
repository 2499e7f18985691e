//! End-to-end smoke test of the training step on a tiny synthetic dataset:
//! a fronto-parallel textured plane seen by a 3-camera rig, so the true
//! disparity between views `r` and `t` is `3 |t - r|` px everywhere.

use super::*;
use crate::augment::{AugmentConfig, augment};
use crate::losses::LossConfig;
use crate::precision::{LossScale, Precision};
use crate::sampling::{Triplet, TripletSampler};
use crate::schedule::OneCycleConfig;
use burn::module::Module;
use burn::tensor::{Device, Tensor, TensorData};
use mbs_core::geometry::{Rig, Side};
use mbs_nets::{CostVolumeNet, CostVolumeNetConfig};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const HEIGHT: usize = 32;
const WIDTH: usize = 96;
const VIEWS: usize = 3;
const STEP_PX: f32 = 8.0;

/// Views of one scene: `view_k(x, y) = texture(x + 3k, y)`, three channels
/// of sums of random sinusoids.
fn scene(rng: &mut ChaCha8Rng) -> Vec<Vec<f32>> {
    let waves: Vec<[f32; 4]> = (0..9)
        .map(|_| {
            [
                rng.random_range(0.1..0.6),
                rng.random_range(-0.3..0.3),
                rng.random_range(0.0..6.3),
                rng.random_range(0.05..0.12),
            ]
        })
        .collect();
    (0..VIEWS)
        .map(|k| {
            let mut image = Vec::with_capacity(3 * HEIGHT * WIDTH);
            for channel in 0..3 {
                for y in 0..HEIGHT {
                    for x in 0..WIDTH {
                        let u = x as f32 + STEP_PX * k as f32;
                        let value: f32 = waves[channel * 3..channel * 3 + 3]
                            .iter()
                            .map(|[fx, fy, phase, amp]| {
                                amp * (fx * u + fy * y as f32 + phase).sin()
                            })
                            .sum();
                        image.push(0.5 + value);
                    }
                }
            }
            image
        })
        .collect()
}

fn stack(images: &[&Vec<f32>], device: &Device) -> Tensor<4> {
    let data: Vec<f32> = images
        .iter()
        .flat_map(|image| image.iter().copied())
        .collect();
    Tensor::from_data(
        TensorData::new(data, [images.len(), 3, HEIGHT, WIDTH]),
        device,
    )
}

fn batch(scenes: &[Vec<Vec<f32>>], triplets: &[Triplet], rig: &Rig, device: &Device) -> StepBatch {
    let pick = |view: fn(&Triplet) -> usize| {
        let images: Vec<&Vec<f32>> = scenes
            .iter()
            .zip(triplets)
            .map(|(s, t)| &s[view(t)])
            .collect();
        stack(&images, device)
    };
    let reference = pick(|t| t.reference);
    let student_target = pick(|t| t.student);
    StepBatch {
        teacher_target: pick(|t| t.teacher),
        // Colour jitter: a brightness gain on the student's input.
        augmented_reference: (reference.clone() * 1.1).clamp(0.0, 1.0),
        augmented_target: (student_target.clone() * 1.1).clamp(0.0, 1.0),
        reference,
        student_target,
        student_sides: triplets.iter().map(|t| t.student_side()).collect(),
        teacher_sides: triplets.iter().map(|t| t.teacher_side()).collect(),
        ratios: triplets.iter().map(|t| t.ratio(rig)).collect(),
    }
}

fn rig() -> Rig {
    Rig {
        num_views: VIEWS,
        baseline_m: 0.5,
        focal_px: 100.0,
        cx: WIDTH as f64 / 2.0,
        cy: HEIGHT as f64 / 2.0,
        width: WIDTH as u32,
        height: HEIGHT as u32,
    }
}

/// A batch of the first two scenes: a right-right item with r = 1/2 and a
/// left-left item with r = 2, which goes through the mirroring.
fn two_item_batch(scenes: &[Vec<Vec<f32>>], device: &Device) -> StepBatch {
    let triplets = [
        Triplet {
            reference: 0,
            student: 1,
            teacher: 2,
        },
        Triplet {
            reference: 2,
            student: 0,
            teacher: 1,
        },
    ];
    batch(&scenes[..2], &triplets, &rig(), device)
}

/// Mean |d_s - truth| of the student on the clean pairs of `fixed` (truth
/// 8 and 16 px, [`two_item_batch`]).
fn student_error(trainer: &S3Trainer<CostVolumeNet>, fixed: &StepBatch) -> f32 {
    let d = mbs_nets::test_util::values(mbs_nets::predict(
        &trainer.student().valid(),
        fixed.reference.clone(),
        fixed.student_target.clone(),
        &fixed.student_sides,
    ));
    let half = d.len() / 2;
    let truth = |i: usize| if i < half { 8.0 } else { 16.0 };
    d.iter()
        .enumerate()
        .map(|(i, v)| (v - truth(i)).abs())
        .sum::<f32>()
        / d.len() as f32
}

/// The losses of `steps` steps on `fixed`, with fresh colour jitter and
/// occlusion of the student's input every step.
fn train_augmented(
    trainer: &mut S3Trainer<CostVolumeNet>,
    fixed: &StepBatch,
    steps: usize,
) -> Vec<f32> {
    let config = AugmentConfig {
        occlusion_min_side: 4,
        occlusion_max_side: 12,
        ..AugmentConfig::default()
    };
    let mut augment_rng = ChaCha8Rng::seed_from_u64(9);
    (0..steps)
        .map(|_| {
            let (augmented_reference, augmented_target) = augment(
                &config,
                fixed.reference.clone(),
                fixed.student_target.clone(),
                &mut augment_rng,
            );
            let step = StepBatch {
                augmented_reference,
                augmented_target,
                ..fixed.clone()
            };
            trainer.step(step).expect("step runs").loss
        })
        .collect()
}

#[test]
fn loss_decreases_over_twenty_steps() {
    let device = Device::flex();
    let train_device = device.clone().autodiff();
    // Seeds the weight initialisation.
    train_device.seed(42);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let scenes: Vec<_> = (0..2).map(|_| scene(&mut rng)).collect();
    let net = CostVolumeNetConfig::new().with_features(8).with_hidden(16);
    let config = TrainerConfig::new(
        LossConfig::new(),
        OneCycleConfig::new(2e-3, 20).with_pct_start(0.1),
    );
    let mut trainer = S3Trainer::new(net.init(32, &train_device).expect("valid net"), &config)
        .expect("valid config");
    // One fixed batch (the loss of random triplets varies more than it
    // falls in 20 steps).
    let fixed = two_item_batch(&scenes, &device);
    let error = |trainer: &S3Trainer<CostVolumeNet>| student_error(trainer, &fixed);
    let error_before = error(&trainer);
    let start = std::time::Instant::now();
    let losses = train_augmented(&mut trainer, &fixed, 20);
    let error_after = error(&trainer);
    println!(
        "20 steps, batch 2, {HEIGHT}x{WIDTH}: {:.0} ms per step; losses {losses:?}; student EPE {error_before} -> {error_after} px",
        start.elapsed().as_secs_f64() * 1e3 / 20.0
    );
    assert!(losses.iter().all(|l| l.is_finite()));
    let first: f32 = losses[..5].iter().sum::<f32>() / 5.0;
    let last: f32 = losses[15..].iter().sum::<f32>() / 5.0;
    assert!(
        last < 0.7 * first,
        "mean loss of steps 0-4 {first}, of steps 15-19 {last}"
    );
    // The disparity itself moves toward the truth (2.84 -> 1.50 px when written).
    assert!(
        error_after < 0.8 * error_before,
        "{error_before} -> {error_after}"
    );
}

#[test]
fn fixed_teacher_stays_fixed_and_ema_teacher_moves() {
    let device = Device::flex();
    let train_device = device.clone().autodiff();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let scenes = vec![scene(&mut rng)];
    let net = CostVolumeNetConfig::new().with_features(4).with_hidden(4);
    let weights = |trainer: &S3Trainer<mbs_nets::CostVolumeNet>| {
        let mut reader = mbs_nets::test_util::FlatParams::default();
        trainer.teacher().visit(&mut reader);
        reader.0
    };
    for ema in [false, true] {
        let config = TrainerConfig::new(LossConfig::new(), OneCycleConfig::new(1e-2, 10))
            .with_ema(ema)
            .with_ema_base(0.5);
        let mut trainer =
            S3Trainer::new(net.init(32, &train_device).expect("valid"), &config).expect("valid");
        let before = weights(&trainer);
        let triplets = [TripletSampler::new(VIEWS, 1).expect("3 views").sample()];
        let report = trainer
            .step(batch(&scenes, &triplets, &rig(), &device))
            .expect("step runs");
        let after = weights(&trainer);
        let moved = before.iter().zip(&after).filter(|(a, b)| a != b).count();
        if ema {
            assert_eq!(report.momentum, 0.5);
            assert!(moved > 0);
        } else {
            assert_eq!(report.momentum, 1.0);
            assert_eq!(moved, 0);
        }
    }
}

/// Step time at a finetuning-like crop; prints, asserts nothing about time.
/// Run with `cargo test -p mbs-train --release -- --ignored --nocapture`.
#[test]
#[ignore = "timing run, several seconds"]
fn step_time_at_256x512() {
    let device = Device::flex();
    let train_device = device.clone().autodiff();
    let (batch, height, width) = (2, 256, 512);
    let net = CostVolumeNetConfig::new();
    let config = TrainerConfig::new(LossConfig::new(), OneCycleConfig::new(2e-4, 100));
    let mut trainer =
        S3Trainer::new(net.init(128, &train_device).expect("valid"), &config).expect("valid");
    let image = || {
        Tensor::<4>::random(
            [batch, 3, height, width],
            burn::tensor::Distribution::Default,
            &device,
        )
    };
    let reference = image();
    let target = image();
    let step = StepBatch {
        teacher_target: image(),
        augmented_reference: reference.clone(),
        augmented_target: target.clone(),
        reference,
        student_target: target,
        student_sides: vec![Side::Right, Side::Left],
        teacher_sides: vec![Side::Right, Side::Right],
        ratios: vec![1.0, 0.5],
    };
    trainer.step(step.clone()).expect("warm-up step");
    let start = std::time::Instant::now();
    for _ in 0..3 {
        trainer.step(step.clone()).expect("step runs");
    }
    println!(
        "S3 step (teacher + student forward, loss, backward, Adam, EMA), batch {batch}, crop {height}x{width}, 128 px: {:.0} ms",
        start.elapsed().as_secs_f64() * 1e3 / 3.0
    );
}

#[test]
fn trainer_config_round_trips_through_json() {
    use burn::config::{Config, config_to_json};
    let config = TrainerConfig::new(
        LossConfig::new().with_occlusion_enhancement(false),
        OneCycleConfig::new(5e-5, 50_000),
    )
    .with_ema(false);
    let json = config_to_json(&config);
    assert!(json.contains("\"occlusion_enhancement\": false"), "{json}");
    let back = TrainerConfig::load_binary(json.as_bytes()).expect("own JSON parses");
    assert_eq!(back.loss, config.loss);
    assert_eq!(back.lr, config.lr);
    assert!(!back.ema);
    assert_eq!(back.ema_base, 0.996);
}

#[test]
fn table3_row_a_trains_without_the_teacher() {
    let device = Device::flex();
    let train_device = device.clone().autodiff();
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let scenes = vec![scene(&mut rng)];
    let net = CostVolumeNetConfig::new().with_features(4).with_hidden(4);
    let config = TrainerConfig::new(
        LossConfig::new().with_geometry(false),
        OneCycleConfig::new(1e-3, 10),
    );
    let mut trainer =
        S3Trainer::new(net.init(16, &train_device).expect("valid"), &config).expect("valid");
    let triplets = [Triplet {
        reference: 1,
        student: 0,
        teacher: 2,
    }];
    let report = trainer
        .step(batch(&scenes, &triplets, &rig(), &device))
        .expect("step runs");
    assert!(report.loss.is_finite() && report.loss > 0.0);
    assert!(report.grad_norm.is_finite());
}

#[test]
fn the_geometry_term_is_off_then_ramps_then_full() {
    let device = Device::flex();
    let train_device = device.clone().autodiff();
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let scenes = vec![scene(&mut rng)];
    let net = CostVolumeNetConfig::new().with_features(4).with_hidden(4);
    // 10 steps: off for 3, rising over 4 (0, 1/4, 2/4, 3/4), then 1.
    let config = TrainerConfig::new(LossConfig::new(), OneCycleConfig::new(1e-3, 10))
        .with_geometry_start(Some(0.3))
        .with_geometry_warmup(Some(0.4));
    let mut trainer =
        S3Trainer::new(net.init(16, &train_device).expect("valid"), &config).expect("valid");
    let triplets = [Triplet {
        reference: 1,
        student: 0,
        teacher: 2,
    }];
    let mut weights = Vec::new();
    for _ in 0..10 {
        weights.push(trainer.geometry_weight());
        trainer
            .step(batch(&scenes, &triplets, &rig(), &device))
            .expect("step runs");
    }
    let expected = [0.0, 0.0, 0.0, 0.0, 0.25, 0.5, 0.75, 1.0, 1.0, 1.0];
    assert_eq!(weights, expected);
}

#[test]
fn sequence_weights_follow_the_official_adjusted_gamma() {
    use crate::step::sequence_weights;
    // 16 iterations: gamma' = 0.9^(15/15) = 0.9; weights 0.9^15 ... 0.9, 1.
    let weights = sequence_weights(16, 0.9, false);
    assert_eq!(weights.len(), 16);
    assert!((weights[15] - 1.0).abs() < 1e-12);
    assert!((weights[14] - 0.9).abs() < 1e-12);
    assert!((weights[0] - 0.9f64.powi(15)).abs() < 1e-12);
    // 4 iterations: gamma' = 0.9^5, so the first weighs 0.9^15 as well.
    let weights = sequence_weights(4, 0.9, false);
    assert!((weights[0] - 0.9f64.powi(15)).abs() < 1e-12);
    assert!((weights[2] - 0.9f64.powi(5)).abs() < 1e-12);
    // Final only, and a single prediction.
    assert_eq!(sequence_weights(3, 0.9, true), [0.0, 0.0, 1.0]);
    assert_eq!(sequence_weights(1, 0.9, false), [1.0]);
}

#[test]
fn an_initial_estimate_weighs_apart_from_the_sequence_as_the_official_igev_loss() {
    use crate::step::PredictionWeights;
    let weights = |initial_weight, final_only| PredictionWeights {
        gamma: 0.9,
        final_only,
        initial_weight,
    };
    // IGEV-Stereo at 3 iterations: the initial disparity weighs 1, the
    // iterations 0.9^(15/2)^2, 0.9^(15/2), 1 (official `sequence_loss`).
    let official = weights(Some(1.0), false).of(4, 1);
    let adjusted = 0.9f64.powf(7.5);
    let expected = [1.0, adjusted * adjusted, adjusted, 1.0];
    for (got, want) in official.iter().zip(expected) {
        assert!((got - want).abs() < 1e-12, "{official:?}");
    }
    // Before the setting: one sequence of 4, the initial weighing 0.9^15.
    let legacy = weights(None, false).of(4, 1);
    assert_eq!(legacy, sequence_weights(4, 0.9, false));
    assert!((legacy[0] - 0.9f64.powi(15)).abs() < 1e-12);
    // No initial estimate (RAFT-Stereo), final only, a single prediction.
    assert_eq!(
        weights(Some(1.0), false).of(3, 0),
        sequence_weights(3, 0.9, false)
    );
    assert_eq!(weights(Some(1.0), true).of(4, 1), [0.0, 0.0, 0.0, 1.0]);
    assert_eq!(weights(Some(0.5), false).of(2, 1), [0.5, 1.0]);
}

/// A batch of one item twice shared by two devices: each share is that
/// item, so the data-parallel step must report the whole batch's loss and
/// gradient norm (the shares weigh one half each) and move the weights as
/// the one-device step. Clipping is off so a wrong weighting shows in the
/// gradient norm (Adam's update hides a scale).
#[test]
fn data_parallel_step_of_twins_matches_the_one_device_step() {
    // Summed in another order, the gradients differ in their last bits;
    // three Adam steps (normalised by the gradients' size) at 1e-2 carry
    // that to about 5e-5 in a weight on a loaded machine. A wrong share or
    // weighting moves weights by about the learning rate.
    data_parallel_twins(Precision::F32, 1e-4);
}

/// The same in f16, where each share's loss is scaled and the summed
/// gradients unscaled once. One device sums the two items' gradients in
/// f16, two devices in f32: the weights differed by up to 1.6e-3 after 3
/// steps when written (f32: 4e-7), hence 1e-2.
#[test]
fn data_parallel_f16_step_of_twins_matches_the_one_device_step() {
    data_parallel_twins(Precision::F16, 1e-2);
}

/// Every weight of `trainer`'s student, flat.
fn student_weights(trainer: &S3Trainer<CostVolumeNet>) -> Vec<f32> {
    let mut reader = mbs_nets::test_util::FlatParams::default();
    trainer.student().visit(&mut reader);
    reader.0
}

/// Two items of one scene with the same triplet on `device`.
fn twin_batch(device: &Device) -> StepBatch {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let scene = scene(&mut rng);
    let triplet = Triplet {
        reference: 0,
        student: 1,
        teacher: 2,
    };
    batch(&[scene.clone(), scene], &[triplet, triplet], &rig(), device)
}

fn data_parallel_twins(precision: Precision, tolerance: f32) {
    let device = Device::flex();
    let train_device = device.clone().autodiff();
    train_device.seed(11);
    let twins = twin_batch(&device);
    let net = CostVolumeNetConfig::new()
        .with_features(4)
        .with_hidden(8)
        .init(32, &train_device)
        .expect("valid");
    let config = TrainerConfig::new(LossConfig::new(), OneCycleConfig::new(1e-2, 10))
        .with_grad_clip_norm(1e9)
        .with_precision(precision)
        .with_initial_loss_scale(32.0);
    let mut single = S3Trainer::new(net.clone(), &config).expect("valid");
    let mut parallel = S3Trainer::new(net, &config).expect("valid");
    let pair = [device.clone(), device.clone()];
    for _ in 0..3 {
        let one = single.step(twins.clone()).expect("step runs");
        let two = parallel
            .step_parallel(twins.clone(), &pair)
            .expect("parallel step runs");
        assert!(
            (one.loss - two.loss).abs() <= tolerance * one.loss.abs(),
            "{one:?} {two:?}"
        );
        assert!(
            (one.grad_norm - two.grad_norm).abs() <= 10.0 * f64::from(tolerance) * one.grad_norm,
            "{one:?} {two:?}"
        );
        assert_eq!(one.loss_scale, two.loss_scale);
    }
    let (a, b) = (student_weights(&parallel), student_weights(&single));
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    println!("{precision}: weights within {worst} of the one-device step's");
    mbs_nets::test_util::assert_close(&a, &b, tolerance);
    let message = parallel
        .step_parallel(twins.split(2).remove(0), &pair)
        .map(|_| ())
        .expect_err("one item cannot be shared")
        .to_string();
    assert!(
        message.contains("cannot be shared by 2 devices"),
        "{message}"
    );
}

/// Mixed precision trains like f32: from the same weights, on the same
/// batches and augmentations, the bf16 and f16 runs' losses follow the f32
/// run's step by step (within 10 %; bf16 was within 6.3 % when written),
/// fall as much, and leave the weights (the f32 masters) in f32. The f16
/// run starts at a loss scale this network's gradients fit (32);
/// `f16_overflow_skips_the_step_and_halves_the_loss_scale` covers finding it.
#[test]
fn mixed_precision_follows_the_f32_loss_curve() {
    use burn::tensor::DType;
    /// The format of every float parameter visited.
    #[derive(Default)]
    struct ParamDtypes(Vec<DType>);
    impl burn::module::ModuleVisitor for ParamDtypes {
        fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<Tensor<D>>) {
            self.0.push(param.val().dtype());
        }
    }
    let setup = MixedPrecisionSetup::new();
    let exact = setup.train(Precision::F32, 20);
    let mean =
        |reports: &[StepReport]| reports.iter().map(|r| r.loss).sum::<f32>() / reports.len() as f32;
    for precision in [Precision::Bf16, Precision::F16] {
        let mut trainer = setup.trainer(precision);
        let mixed = setup.train_on(&mut trainer, 20);
        let worst = exact
            .iter()
            .zip(&mixed)
            .map(|(a, b)| (a.loss - b.loss).abs() / a.loss)
            .fold(0.0, f32::max);
        println!("{precision}: losses within {:.1} % of f32's", 100.0 * worst);
        for (step, (a, b)) in exact.iter().zip(&mixed).enumerate() {
            assert!(
                (a.loss - b.loss).abs() <= 0.1 * a.loss,
                "{precision} step {step}: loss {} against f32's {}",
                b.loss,
                a.loss
            );
            assert!(b.grad_norm.is_finite(), "{precision} step {step}: {b:?}");
        }
        let (first, last) = (mean(&mixed[..5]), mean(&mixed[15..]));
        assert!(last < 0.7 * first, "{precision}: {first} -> {last}");
        let mut dtypes = ParamDtypes::default();
        trainer.student().visit(&mut dtypes);
        trainer.teacher().visit(&mut dtypes);
        assert!(dtypes.0.len() > 10);
        assert!(dtypes.0.iter().all(|d| *d == DType::F32), "{:?}", dtypes.0);
    }
}

/// An f16 run begins at PyTorch's loss scale, 65536, at which this
/// network's gradients overflow f16: such a step changes no weight, halves
/// the scale and reports a gradient norm that is not finite, until the
/// scale fits and a step is taken. f32 and bf16 runs have no loss scale.
#[test]
fn f16_overflow_skips_the_step_and_halves_the_loss_scale() {
    let setup = MixedPrecisionSetup::new();
    for precision in [Precision::F32, Precision::Bf16] {
        assert_eq!(setup.trainer(precision).loss_scale(), None);
    }
    let config = setup
        .config(Precision::F16)
        .with_initial_loss_scale(LossScale::PYTORCH_INITIAL);
    let mut trainer = S3Trainer::new(setup.net.clone(), &config).expect("valid config");
    let weights = |trainer: &S3Trainer<CostVolumeNet>| {
        let mut reader = mbs_nets::test_util::FlatParams::default();
        trainer.student().visit(&mut reader);
        trainer.teacher().visit(&mut reader);
        reader.0
    };
    let mut scale = 65536.0;
    for _ in 0..16 {
        assert_eq!(trainer.loss_scale().map(|s| s.scale), Some(scale));
        let before = weights(&trainer);
        let report = setup.train_on(&mut trainer, 1).remove(0);
        if report.grad_norm.is_finite() {
            assert!(scale < 65536.0, "no step overflowed");
            assert_ne!(weights(&trainer), before);
            return;
        }
        assert_eq!(
            weights(&trainer),
            before,
            "an overflowing step moved the weights"
        );
        scale /= 2.0;
    }
    panic!("still overflowing at a loss scale of {scale}");
}

/// Two scenes, one fixed batch and a compact network, for the
/// mixed-precision tests.
struct MixedPrecisionSetup {
    net: CostVolumeNet,
    fixed: StepBatch,
}

impl MixedPrecisionSetup {
    fn new() -> Self {
        let train_device = Device::flex().autodiff();
        let _drawing = crate::WEIGHT_DRAWING
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        train_device.seed(17);
        let net = CostVolumeNetConfig::new()
            .with_features(8)
            .with_hidden(16)
            .init(32, &train_device)
            .expect("valid net");
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let scenes: Vec<_> = (0..2).map(|_| scene(&mut rng)).collect();
        let fixed = two_item_batch(&scenes, &Device::flex());
        Self { net, fixed }
    }

    fn config(&self, precision: Precision) -> TrainerConfig {
        TrainerConfig::new(
            LossConfig::new(),
            OneCycleConfig::new(2e-3, 20).with_pct_start(0.1),
        )
        .with_precision(precision)
        .with_initial_loss_scale(32.0)
    }

    /// A trainer of the network; an f16 one starts at a loss scale of 32.
    fn trainer(&self, precision: Precision) -> S3Trainer<CostVolumeNet> {
        S3Trainer::new(self.net.clone(), &self.config(precision)).expect("valid config")
    }

    /// `steps` steps on the fixed batch, the student's input freshly
    /// jittered and occluded each step (the same way for every trainer).
    fn train_on(&self, trainer: &mut S3Trainer<CostVolumeNet>, steps: usize) -> Vec<StepReport> {
        let config = AugmentConfig {
            occlusion_min_side: 4,
            occlusion_max_side: 12,
            ..AugmentConfig::default()
        };
        (0..steps)
            .map(|_| {
                let mut rng = ChaCha8Rng::seed_from_u64(9 + trainer.steps_taken() as u64);
                let (augmented_reference, augmented_target) = augment(
                    &config,
                    self.fixed.reference.clone(),
                    self.fixed.student_target.clone(),
                    &mut rng,
                );
                let step = StepBatch {
                    augmented_reference,
                    augmented_target,
                    ..self.fixed.clone()
                };
                trainer.step(step).expect("step runs")
            })
            .collect()
    }

    fn train(&self, precision: Precision, steps: usize) -> Vec<StepReport> {
        self.train_on(&mut self.trainer(precision), steps)
    }
}

/// IGEV-Stereo through a whole S3 step: every trained part moves.
#[test]
fn one_s3_step_updates_every_part_and_pads_odd_sizes() {
    use burn::tensor::Distribution;
    use mbs_core::geometry::Side;
    use mbs_nets::IgevStereoConfig;
    use mbs_nets::official::export_state_dict;

    let device = Device::flex();
    let train_device = device.clone().autodiff();
    let config = IgevStereoConfig::new()
        .with_hidden_dim(16)
        .with_gru_levels(2)
        .with_max_disp(32)
        .with_train_iters(2)
        .with_test_iters(2);
    let net = config.init(&train_device).expect("valid");
    let before = export_state_dict(&net).0;
    let trainer_config = TrainerConfig::new(LossConfig::new(), OneCycleConfig::new(1e-3, 4));
    let mut trainer = S3Trainer::new(net, &trainer_config).expect("valid");
    // 40x70: not multiples of 32, so the padding and the crop run too.
    let image = || Tensor::<4>::random([1, 3, 40, 70], Distribution::Default, &device);
    let (reference, target) = (image(), image());
    let batch = StepBatch {
        augmented_reference: reference.clone(),
        augmented_target: target.clone(),
        reference,
        student_target: target.clone(),
        teacher_target: target,
        student_sides: vec![Side::Left],
        teacher_sides: vec![Side::Right],
        ratios: vec![0.5],
    };
    let report = trainer.step(batch).expect("a step");
    assert!(
        report.loss.is_finite() && report.grad_norm > 0.0,
        "{report:?}"
    );
    let after = export_state_dict(trainer.student()).0;
    // Every trained part moved: the MobileNetV2 stem, the 3-D hourglass,
    // the context encoder, the GRU and both upsampling heads.
    for key in [
        "feature.conv_stem.weight",
        "cost_agg.conv1.0.conv.weight",
        "classifier.weight",
        "cnet.conv1.weight",
        "update_block.gru04.convz.weight",
        "spx.0.weight",
        "spx_gru.0.weight",
    ] {
        assert_ne!(
            before.tensors[key], after.tensors[key],
            "{key} did not change"
        );
    }
}
