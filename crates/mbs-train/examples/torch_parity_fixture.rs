//! Writes the fixture of `mbs.torch`'s parity tests
//! (`python/tests/test_torch_loss.py`): fixed inputs, and for each case (a
//! loss configuration, a geometry weight, one or three student
//! predictions) the value of every term, the masks and the weight map of
//! [`S3Loss`] and the gradient of its total in each student prediction;
//! then one batch's augmentation draws and the augmented pair
//! ([`mbs_train::augment::apply`]).
//!
//! ```text
//! cargo run -p mbs-train --example torch_parity_fixture -- python/tests/fixtures/torch_parity.safetensors
//! ```
//!
//! The inputs are smooth analytic images (two items, 3x14x22) and targets
//! shifted by a disparity field, one item's targets on the right and one's
//! on the left, with student and teacher disparities near the true ones
//! but a patch that leaves the image and one below zero, so that every
//! mask and the range term have something to do. Tensors are named
//! `inputs/<name>`, `<case>/<name>` and `augment/<name>`; the metadata holds each case's
//! loss configuration (the keys of `trainer.loss`, as `mbs.torch.S3Loss`'s
//! arguments), geometry weight and prediction count.

use std::collections::HashMap;
use std::error::Error;
use std::path::{Path, PathBuf};

use burn::tensor::{Device, Tensor};
use mbs_core::geometry::Side;
use mbs_nets::test_util::{tensor4, values};
use mbs_train::augment::{AugmentConfig, apply};
use mbs_train::step::sequence_weights;
use mbs_train::{LossConfig, LossInputs, LossOutput, S3Loss};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use safetensors::tensor::{Dtype, TensorView};

const BATCH: usize = 2;
const HEIGHT: usize = 14;
const WIDTH: usize = 22;
/// Baseline ratio `B_s / B_t` of each item.
const RATIOS: [f64; BATCH] = [0.5, 0.8];
/// Side of each item's targets.
const SIDES: [Side; BATCH] = [Side::Right, Side::Left];
/// Decay of the sequence case's earlier predictions.
const SEQUENCE_GAMMA: f64 = 0.9;

/// The texture every image samples, in `[0.1, 0.9]`; flat along x in
/// the top rows.
fn texture(x: f64, y: f64, channel: usize, item: usize) -> f64 {
    let c = channel as f64;
    if y < 6.0 {
        // Rows without texture along x: the un-warped target matches
        // there as well as any warp, which auto-masking rejects.
        return 0.3 + 0.1 * y + 0.1 * c;
    }
    0.5 + 0.25 * (0.9 * x + 0.4 * y + c + item as f64).sin()
        + 0.15 * (0.35 * x * (c + 1.0) - 0.8 * y).cos()
}

/// The disparity field between reference and student target (px).
fn disparity(x: f64, y: f64) -> f64 {
    1.0 + 0.08 * x + 0.05 * y
}

/// `[B, C, H, W]` image whose pixel `(x, y)` is the texture at `x + sign
/// * scale * disparity(x, y)` (`scale` 0: the reference).
fn image(scale: [f64; BATCH]) -> Vec<f32> {
    let mut out = Vec::with_capacity(BATCH * 3 * HEIGHT * WIDTH);
    for item in 0..BATCH {
        let sign = match SIDES[item] {
            Side::Right => 1.0,
            Side::Left => -1.0,
        };
        for channel in 0..3 {
            for y in 0..HEIGHT {
                for x in 0..WIDTH {
                    let (x, y) = (x as f64, y as f64);
                    let source = x + sign * scale[item] * disparity(x, y);
                    out.push(texture(source, y, channel, item) as f32);
                }
            }
        }
    }
    out
}

/// `[B, 1, H, W]` disparities: the true field times `scale`, a wobble of
/// `noise` px, and (for `escape`) a patch far outside the image and one
/// below zero.
fn prediction(scale: [f64; BATCH], noise: f64, escape: bool) -> Vec<f32> {
    let mut out = Vec::with_capacity(BATCH * HEIGHT * WIDTH);
    for (item, scale) in scale.iter().enumerate() {
        for y in 0..HEIGHT {
            for x in 0..WIDTH {
                let (xf, yf) = (x as f64, y as f64);
                let wobble = noise * (0.5 * xf + 0.3 * yf + item as f64).sin();
                let value = match (escape, x, y) {
                    (true, 15..=18, 2..=5) => 40.0 + xf,
                    (true, 2..=4, 9..=11) => -3.05 - yf * 0.1,
                    _ => scale * disparity(xf, yf) + wobble,
                };
                out.push(value as f32);
            }
        }
    }
    out
}

/// One configuration of the loss to compare.
struct Case {
    name: &'static str,
    config: LossConfig,
    geometry_weight: f64,
    predictions: usize,
}

/// The cases: each of [`configurations`] at geometry weight 1 with one
/// prediction, then the default loss at half the geometry weight and over
/// a sequence of three predictions.
fn cases() -> Vec<Case> {
    let case = |name, config, geometry_weight, predictions| Case {
        name,
        config,
        geometry_weight,
        predictions,
    };
    let mut cases: Vec<Case> = configurations()
        .into_iter()
        .map(|(name, config)| case(name, config, 1.0, 1))
        .collect();
    cases.push(case("half_geometry", LossConfig::new(), 0.5, 1));
    cases.push(case("sequence", LossConfig::new(), 1.0, 3));
    cases
}

/// The loss configurations compared, by case name: the default, the
/// paper's, each part switched off and each other setting changed.
fn configurations() -> Vec<(&'static str, LossConfig)> {
    let base = LossConfig::new;
    vec![
        ("default", base()),
        (
            "paper",
            base()
                .with_range_weight(0.0)
                .with_out_of_view_invalid(false),
        ),
        ("no_geometry", base().with_geometry(false)),
        ("no_photometric", base().with_photometric(false)),
        ("no_smoothness", base().with_smoothness(false)),
        ("no_threshold", base().with_threshold_filter(false)),
        ("no_auto_mask", base().with_auto_mask(false)),
        (
            "no_occlusion_enhancement",
            base().with_occlusion_enhancement(false),
        ),
        (
            "normalised_smoothness",
            base().with_normalise_smoothness(true),
        ),
        ("capped", base().with_max_target_disparity(2.0)),
        ("scale_match", base().with_geometry_scale_match(true)),
        (
            "photometric_mask_mean",
            base().with_photometric_mask_mean(true),
        ),
        (
            "outside_mask_weight",
            base()
                .with_outside_mask_weight(0.1)
                .with_photometric_mask_mean(true),
        ),
        ("view", base().with_view_weight(0.5)),
        (
            "other_weights",
            base()
                .with_ssim_window(3)
                .with_alpha(0.5)
                .with_tau(0.2)
                .with_omega(3.0)
                .with_lambda_p(5.0)
                .with_lambda_s_ratio(0.01)
                .with_range_weight(0.5),
        ),
    ]
}

/// Named row-major f32 tensors and their shapes.
#[derive(Default)]
struct Fixture {
    tensors: Vec<(String, Vec<usize>, Vec<u8>)>,
    metadata: HashMap<String, String>,
}

impl Fixture {
    fn add(&mut self, name: String, shape: &[usize], data: &[f32]) {
        let bytes = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.tensors.push((name, shape.to_vec(), bytes));
    }

    fn add_tensor<const D: usize>(&mut self, name: String, tensor: Tensor<D>) {
        let shape = tensor.dims().to_vec();
        self.add(name, &shape, &values(tensor));
    }

    fn write(self, path: &Path) -> Result<(), Box<dyn Error>> {
        let views = self
            .tensors
            .iter()
            .map(|(name, shape, bytes)| {
                Ok((
                    name.clone(),
                    TensorView::new(Dtype::F32, shape.clone(), bytes)?,
                ))
            })
            .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()?;
        safetensors::serialize_to_file(views, Some(self.metadata), path)?;
        Ok(())
    }
}

/// An input of every case: its name, values and shape.
type Input = (&'static str, Vec<f32>, [usize; 4]);

/// Shape of the images.
const IMAGE_SHAPE: [usize; 4] = [BATCH, 3, HEIGHT, WIDTH];
/// Shape of the disparities and the occlusion map.
const MAP_SHAPE: [usize; 4] = [BATCH, 1, HEIGHT, WIDTH];

/// The images and disparities every case reads: reference, targets,
/// teacher disparity, then the student's predictions (the last ones are
/// a case's).
fn inputs() -> [Input; 7] {
    let teacher_scale = RATIOS.map(|r| 1.0 / r);
    [
        ("reference", image([0.0; BATCH]), IMAGE_SHAPE),
        ("student_target", image([1.0; BATCH]), IMAGE_SHAPE),
        ("teacher_target", image(teacher_scale), IMAGE_SHAPE),
        (
            "teacher_disparity",
            prediction(teacher_scale, 0.15, true),
            MAP_SHAPE,
        ),
        (
            "student_disparity_0",
            prediction([0.8; BATCH], 0.6, false),
            MAP_SHAPE,
        ),
        (
            "student_disparity_1",
            prediction([0.9; BATCH], 0.5, true),
            MAP_SHAPE,
        ),
        (
            "student_disparity_2",
            prediction([1.0; BATCH], 0.4, true),
            MAP_SHAPE,
        ),
    ]
}

fn main() -> Result<(), Box<dyn Error>> {
    let path: PathBuf = std::env::args()
        .nth(1)
        .ok_or("usage: s3_loss_fixture OUT.safetensors")?
        .into();
    let device = Device::flex().autodiff();
    let inputs = inputs();
    let mut fixture = Fixture::default();
    for (name, data, shape) in &inputs {
        fixture.add(format!("inputs/{name}"), shape, data);
    }
    fixture.add("inputs/ratios".into(), &[BATCH], &RATIOS.map(|r| r as f32));
    fixture.add(
        "inputs/signs".into(),
        &[BATCH],
        &SIDES.map(|side| if side == Side::Right { 1.0 } else { -1.0 }),
    );
    let mut described = Vec::new();
    for case in cases() {
        described.push(add_case(&mut fixture, &case, &inputs, &device)?);
    }
    fixture
        .metadata
        .insert("cases".into(), serde_json::to_string(&described)?);
    add_augmentation(&mut fixture, &inputs);
    fixture.write(&path)?;
    println!("{} cases -> {}", described.len(), path.display());
    Ok(())
}

/// Computes `case`'s loss on `inputs` and adds the gradient of its total in
/// each student prediction, its terms and its maps to `fixture`; returns
/// the case's description for the metadata.
fn add_case(
    fixture: &mut Fixture,
    case: &Case,
    inputs: &[Input],
    device: &Device,
) -> Result<serde_json::Value, Box<dyn Error>> {
    let tensor = |index: usize| {
        let (_, data, shape) = &inputs[index];
        tensor4(data, *shape, device)
    };
    let predictions: Vec<Tensor<4>> = (0..case.predictions)
        .map(|i| tensor(inputs.len() - case.predictions + i).require_grad())
        .collect();
    let weights = sequence_weights(predictions.len(), SEQUENCE_GAMMA, false);
    let (last, earlier) = predictions.split_last().ok_or("a case has no prediction")?;
    let loss = S3Loss::new(case.config.clone())?;
    let out = loss.compute_sequence(
        LossInputs {
            reference: tensor(0),
            student_target: tensor(1),
            teacher_target: tensor(2),
            student_disparity: last.clone(),
            teacher_disparity: tensor(3),
            student_sides: SIDES.to_vec(),
            teacher_sides: SIDES.to_vec(),
            ratios: RATIOS.to_vec(),
            geometry_weight: case.geometry_weight,
        },
        earlier.iter().cloned().zip(weights).collect(),
    )?;
    let name = case.name;
    let gradients = out.total.backward();
    for (i, prediction) in predictions.iter().enumerate() {
        let grad = prediction.grad(&gradients).ok_or("no gradient")?;
        fixture.add_tensor(format!("{name}/grad_{i}"), grad);
    }
    add_outputs(fixture, name, out);
    Ok(serde_json::json!({
        "name": name,
        "config": serde_json::to_value(&case.config)?,
        "geometry_weight": case.geometry_weight,
        "predictions": case.predictions,
        "sequence_gamma": SEQUENCE_GAMMA,
    }))
}

/// Adds the total, each term that is on and each map there is of the
/// case `name`'s loss output `out` to `fixture`.
fn add_outputs(fixture: &mut Fixture, name: &str, out: LossOutput) {
    let terms = out
        .terms
        .iter()
        .map(|(term, value)| (term.name(), value.cloned()));
    let scalars = std::iter::once(("total", Some(out.total))).chain(terms);
    for (part, value) in scalars {
        if let Some(value) = value {
            fixture.add_tensor(format!("{name}/{part}"), value.detach().without_autodiff());
        }
    }
    let maps = [
        ("student_mask", out.student_mask),
        ("teacher_mask", out.teacher_mask),
        ("weight_map", out.weight_map),
    ];
    for (part, map) in maps {
        if let Some(map) = map {
            fixture.add_tensor(format!("{name}/{part}"), map.detach().without_autodiff());
        }
    }
}

/// Adds one batch's augmentation draws (seed 7, an occlusion in every
/// item) and the pair they augment, `inputs`' reference and student
/// target, to `fixture`.
fn add_augmentation(fixture: &mut Fixture, inputs: &[Input]) {
    let plain = Device::flex();
    let augment = AugmentConfig {
        occlusion_probability: 1.0,
        occlusion_min_side: 3,
        occlusion_max_side: 8,
        ..AugmentConfig::default()
    };
    let draws = augment.draw(BATCH, HEIGHT, WIDTH, &mut ChaCha8Rng::seed_from_u64(7));
    let (reference, target) = apply(
        &draws,
        tensor4(&inputs[0].1, IMAGE_SHAPE, &plain),
        tensor4(&inputs[1].1, IMAGE_SHAPE, &plain),
    );
    fixture.add("augment/brightness".into(), &[BATCH], &draws.brightness);
    fixture.add("augment/contrast".into(), &[BATCH], &draws.contrast);
    fixture.add("augment/saturation".into(), &[BATCH], &draws.saturation);
    fixture.add("augment/occlusion".into(), &MAP_SHAPE, &draws.occlusion);
    fixture.add_tensor("augment/reference".into(), reference);
    fixture.add_tensor("augment/target".into(), target);
}
