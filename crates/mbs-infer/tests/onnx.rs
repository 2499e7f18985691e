//! ONNX backends on real ONNX Runtime with the test models of
//! `testdata/onnx/` (made by `tools/onnx/make_test_models.py`), whose
//! outputs are exact functions of their inputs. The runtime comes from
//! `tools/setup-ort.sh` (`tools/test.sh` runs it): without it these tests
//! fail, they never skip.

use std::path::PathBuf;

use image::{Luma, Rgb};
use mbs_core::{MaskImage, RgbImage};
use mbs_infer::StereoMatcher;
use mbs_infer::inpaint::Inpainter;
use mbs_infer::onnx::{ModelCard, OnnxInpainter, OnnxStereo, RuntimeOptions};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/onnx")
        .join(name)
}

fn card(name: &str) -> ModelCard {
    ModelCard::from_file(&fixture(name)).expect("test cards are valid")
}

fn stereo(model: &str, card_name: &str) -> OnnxStereo {
    OnnxStereo::open(&fixture(model), card(card_name), &RuntimeOptions::default())
        .unwrap_or_else(|e| panic!("{e}"))
}

fn inpainter(model: &str, card_name: &str) -> OnnxInpainter {
    OnnxInpainter::open(&fixture(model), card(card_name), &RuntimeOptions::default())
        .unwrap_or_else(|e| panic!("{e}"))
}

/// A deterministic texture, different per `seed`.
fn texture(width: u32, height: u32, seed: u32) -> RgbImage {
    RgbImage::from_fn(width, height, |x, y| {
        Rgb(std::array::from_fn(|c| {
            ((x * 7 + y * 13 + c as u32 * 29 + seed * 31).wrapping_mul(2654435761) >> 24) as u8
        }))
    })
}

fn mean(image: &RgbImage, x: u32, y: u32) -> f32 {
    image
        .get_pixel(x, y)
        .0
        .iter()
        .map(|&v| f32::from(v))
        .sum::<f32>()
        / 3.0
}

/// What the test stereo models compute at `(x, y)`; `x + 1` must be inside.
fn model_function(left: &RgbImage, right: &RgbImage, x: u32, y: u32) -> f32 {
    0.5 * mean(left, x, y) + 0.25 * mean(right, x + 1, y) + 1.0
}

#[test]
fn dynamic_models_get_padded_inputs_and_cropped_outputs() {
    let matcher = stereo("stereo_dynamic.onnx", "stereo_dynamic.json");
    // 37x21 is no multiple of 8: padded to 40x24 (1 column left, 2 right,
    // 3 rows on top), which the model's SpaceToDepth needs.
    let (left, right) = (texture(37, 21, 1), texture(37, 21, 2));
    let out = matcher.predict(&left, &right).unwrap();
    assert_eq!(out.disparity.dimensions(), (37, 21));
    for y in 0..21 {
        for x in 0..36 {
            let expected = model_function(&left, &right, x, y);
            let got = out.disparity.get_pixel(x, y).0[0];
            assert!(
                (got - expected).abs() < 1e-3,
                "({x}, {y}): {got} vs {expected}"
            );
        }
    }
    assert!(out.valid.iter().all(|&v| v == 255));
}

#[test]
fn without_padding_the_model_refuses_the_size() {
    let mut unpadded = card("stereo_dynamic.json");
    unpadded.size = mbs_infer::onnx::card::SizePolicy::Dynamic {
        multiple: 1,
        horizontal: Default::default(),
        vertical: Default::default(),
        fill: Default::default(),
    };
    let matcher = OnnxStereo::open(
        &fixture("stereo_dynamic.onnx"),
        unpadded,
        &RuntimeOptions::default(),
    )
    .unwrap();
    let err = matcher
        .predict(&texture(37, 21, 1), &texture(37, 21, 2))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("stereo_dynamic.onnx: inference failed"),
        "{err}"
    );
}

#[test]
fn right_views_are_predicted_by_mirroring() {
    let matcher = stereo("stereo_dynamic.onnx", "stereo_dynamic.json");
    let (left, right) = (texture(40, 16, 3), texture(40, 16, 4));
    let out = matcher.predict_right(&left, &right).unwrap();
    // Mirrored, the right view is the reference and the left the target;
    // the model's "x + 1" neighbour becomes x - 1 once mirrored back.
    for y in 0..16 {
        for x in 1..40 {
            let expected = 0.5 * mean(&right, x, y) + 0.25 * mean(&left, x - 1, y) + 1.0;
            let got = out.disparity.get_pixel(x, y).0[0];
            assert!(
                (got - expected).abs() < 1e-3,
                "({x}, {y}): {got} vs {expected}"
            );
        }
    }
}

#[test]
fn negative_sign_cards_turn_flow_into_disparity() {
    let (left, right) = (texture(24, 16, 5), texture(24, 16, 6));
    let reference = stereo("stereo_dynamic.onnx", "stereo_dynamic.json")
        .predict(&left, &right)
        .unwrap();
    let flipped = stereo("stereo_negative.onnx", "stereo_negative.json")
        .predict(&left, &right)
        .unwrap();
    assert_eq!(flipped, reference);
    // Read with the wrong sign, every value is negative, so invalid: a map
    // with no value at all is refused, never handed on as a prediction.
    let mut wrong = card("stereo_negative.json");
    wrong.output.sign = 1.0;
    let wrong = OnnxStereo::open(
        &fixture("stereo_negative.onnx"),
        wrong,
        &RuntimeOptions::default(),
    )
    .unwrap();
    let err = wrong.predict(&left, &right).unwrap_err().to_string();
    assert!(
        err.contains("onnx:test-stereo-negative gave no usable disparity: it has no finite value"),
        "{err}"
    );
}

#[test]
fn fixed_size_models_see_resized_views_and_scale_the_disparity() {
    let matcher = stereo("stereo_fixed.onnx", "stereo_fixed.json");
    // 96x64 is twice the model's 48x32: constant views resize exactly, the
    // model gives 0.5 * 100 + 0.25 * 40 + 1 = 61 at 48 px wide, i.e. 122
    // at 96 px (its last column sees zero padding, so skip the right edge).
    let left = RgbImage::from_pixel(96, 64, Rgb([100; 3]));
    let right = RgbImage::from_pixel(96, 64, Rgb([40; 3]));
    let out = matcher.predict(&left, &right).unwrap();
    assert_eq!(out.disparity.dimensions(), (96, 64));
    for (x, y, d) in out.disparity.enumerate_pixels() {
        if x < 90 {
            assert!((d.0[0] - 122.0).abs() < 1e-3, "({x}, {y}): {}", d.0[0]);
        }
    }
}

#[test]
fn batches_give_the_same_disparities_as_single_runs() {
    let matcher = stereo("stereo_dynamic.onnx", "stereo_dynamic.json");
    let views: Vec<(RgbImage, RgbImage)> = (0..3)
        .map(|k| (texture(30, 20, k), texture(30, 20, k + 10)))
        .collect();
    let pairs: Vec<(&RgbImage, &RgbImage)> = views.iter().map(|(l, r)| (l, r)).collect();
    let batch = matcher.predict_batch(&pairs).unwrap();
    assert_eq!(batch.len(), 3);
    for ((l, r), batched) in pairs.iter().zip(&batch) {
        assert_eq!(&matcher.predict(l, r).unwrap(), batched);
    }
    assert_ne!(batch[0], batch[1]);
}

#[test]
fn lama_style_masks_fill_holes_through_a_window_of_the_model_size() {
    let inpainter = inpainter("inpaint_lama.onnx", "inpaint_lama.json");
    let image = texture(200, 150, 7);
    let mut mask = MaskImage::new(200, 150);
    for y in 100..110 {
        for x in 150..160 {
            mask.put_pixel(x, y, Luma([255]));
        }
    }
    let out = inpainter.inpaint(&image, &mask, None).unwrap();
    // The 10x10 hole fits the 64x64 model: no resampling, holes become
    // 0.5 * 255 = 127.5 -> 128, every other pixel is untouched.
    for (x, y, p) in out.enumerate_pixels() {
        let expected = if mask.get_pixel(x, y).0[0] != 0 {
            Rgb([128; 3])
        } else {
            *image.get_pixel(x, y)
        };
        assert_eq!(*p, expected, "({x}, {y})");
    }
}

#[test]
fn holes_larger_than_a_fixed_model_are_resized_and_composited() {
    let inpainter = inpainter("inpaint_lama.onnx", "inpaint_lama.json");
    let image = RgbImage::from_pixel(300, 200, Rgb([200, 100, 50]));
    let mut mask = MaskImage::new(300, 200);
    let hole = |x: u32, y: u32| (60..200).contains(&x) && (80..120).contains(&y);
    for (x, y, m) in mask.enumerate_pixels_mut() {
        if hole(x, y) {
            *m = Luma([255]);
        }
    }
    let out = inpainter.inpaint(&image, &mask, None).unwrap();
    for (x, y, p) in out.enumerate_pixels() {
        let inner = hole(x.saturating_sub(8), y.saturating_sub(8)) && hole(x + 8, y + 8);
        if !hole(x, y) {
            assert_eq!(*p, Rgb([200, 100, 50]), "({x}, {y}) is kept");
        } else if inner {
            assert_eq!(*p, Rgb([128; 3]), "({x}, {y}) is filled");
        }
    }
}

#[test]
fn migan_style_masks_keep_255_and_fill_0() {
    let inpainter = inpainter("inpaint_migan.onnx", "inpaint_migan.json");
    let image = texture(33, 17, 9);
    let mask = MaskImage::from_fn(33, 17, |x, y| {
        Luma([if (x + y) % 5 == 0 { 255 } else { 0 }])
    });
    let out = inpainter.inpaint(&image, &mask, None).unwrap();
    for (x, y, p) in out.enumerate_pixels() {
        let expected = if mask.get_pixel(x, y).0[0] != 0 {
            Rgb([77; 3])
        } else {
            *image.get_pixel(x, y)
        };
        assert_eq!(*p, expected, "({x}, {y})");
    }
}

#[test]
fn missing_and_corrupt_model_files_are_named() {
    let options = RuntimeOptions::default();
    let missing = fixture("no_such_model.onnx");
    let err = OnnxStereo::open(&missing, card("stereo_dynamic.json"), &options)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("no_such_model.onnx: cannot load the ONNX model: no such file"),
        "{err}"
    );
    let dir = tempfile::tempdir().unwrap();
    let corrupt = dir.path().join("corrupt.onnx");
    std::fs::write(&corrupt, b"this is not a protobuf").unwrap();
    let err = OnnxStereo::open(&corrupt, card("stereo_dynamic.json"), &options)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("corrupt.onnx: cannot load the ONNX model"),
        "{err}"
    );
}

#[test]
fn wrong_input_names_are_named() {
    let mut wrong = card("stereo_dynamic.json");
    wrong.inputs.insert("left".into(), "left_image".into());
    let err = OnnxStereo::open(
        &fixture("stereo_dynamic.onnx"),
        wrong,
        &RuntimeOptions::default(),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        err.contains("does not match card test-stereo-dynamic"),
        "{err}"
    );
    assert!(
        err.contains("\"left\" is not in the card's inputs") || err.contains("\"left_image\""),
        "{err}"
    );
}

#[test]
fn cards_that_do_not_fit_the_model_are_refused() {
    let options = RuntimeOptions::default();
    let open_stereo = |model: &str, card: ModelCard| {
        OnnxStereo::open(&fixture(model), card, &options)
            .err()
            .unwrap()
            .to_string()
    };
    let open_inpaint = |model: &str, card: ModelCard| {
        OnnxInpainter::open(&fixture(model), card, &options)
            .err()
            .unwrap()
            .to_string()
    };
    // A dynamic card on a fixed-size model.
    let err = open_stereo("stereo_fixed.onnx", card("stereo_dynamic.json"));
    assert!(err.contains("has a fixed size (48x32)"), "{err}");
    // A fixed card of another size.
    let mut other_size = card("stereo_fixed.json");
    other_size.size = mbs_infer::onnx::card::SizePolicy::Fixed {
        width: 64,
        height: 32,
    };
    let err = open_stereo("stereo_fixed.onnx", other_size);
    assert!(
        err.contains("is 48x32 (width x height); the card says 64x32"),
        "{err}"
    );
    // A uint8 card on a float model, and the other way round.
    let err = open_inpaint("inpaint_lama.onnx", card("inpaint_migan.json"));
    assert!(
        err.contains("holds Float32 values; the card says Uint8"),
        "{err}"
    );
    // The wrong output name, listing the model's outputs.
    let mut no_output = card("stereo_dynamic.json");
    no_output.output.name = "disp".into();
    let err = open_stereo("stereo_dynamic.onnx", no_output);
    assert!(
        err.contains("output \"disp\" is not an output of the model (its outputs: disparity)"),
        "{err}"
    );
    // An inpainting card for a stereo model.
    let err = open_stereo("stereo_dynamic.onnx", card("inpaint_lama.json"));
    assert!(
        err.contains("is an inpainting card; this needs a stereo card"),
        "{err}"
    );
}
