//! Times an ONNX stereo model through mbs; called by
//! `tools/bench/onnx_vs_python.py`. Run in release:
//!
//! ```text
//! cargo run --release -p mbs-infer --example onnx_bench -- \
//!     MODEL CARD WIDTH HEIGHT REPEATS THREADS
//! ```
//!
//! On a synthetic WIDTH x HEIGHT pair, times REPEATS calls of
//! `OnnxStereo::predict` (pre-processing, inference, post-processing) and
//! REPEATS bare model runs on tensors of the padded size with the output
//! copied out (the same work Python's `InferenceSession.run` does). Prints one JSON
//! object with the per-frame times in milliseconds.

use std::path::Path;
use std::time::Instant;

use mbs_core::RgbImage;
use mbs_infer::StereoMatcher;
use mbs_infer::onnx::card::Task;
use mbs_infer::onnx::model::Model;
use mbs_infer::onnx::tensor::Padding;
use mbs_infer::onnx::{ModelCard, OnnxStereo, RuntimeOptions};

type BoxError = Box<dyn std::error::Error>;

fn texture(width: u32, height: u32, seed: u32) -> RgbImage {
    RgbImage::from_fn(width, height, |x, y| {
        image::Rgb(std::array::from_fn(|c| {
            ((x * 7 + y * 13 + c as u32 * 29 + seed * 31).wrapping_mul(2654435761) >> 24) as u8
        }))
    })
}

fn millis(times: &mut [f64]) -> (f64, f64) {
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], times[0])
}

fn main() -> Result<(), BoxError> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, card, width, height, repeats, threads] = args.as_slice() else {
        return Err("usage: onnx_bench MODEL CARD WIDTH HEIGHT REPEATS THREADS".into());
    };
    let (width, height): (u32, u32) = (width.parse()?, height.parse()?);
    let repeats: usize = repeats.parse()?;
    let options = RuntimeOptions {
        intra_threads: threads.parse()?,
        ..RuntimeOptions::default()
    };
    let card = ModelCard::load(card)?;
    let stereo = OnnxStereo::open(Path::new(model), card.clone(), &options)?;
    let (left, right) = (texture(width, height, 1), texture(width, height, 2));
    stereo.predict(&left, &right)?; // warm-up
    let mut full = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let start = Instant::now();
        stereo.predict(&left, &right)?;
        full.push(start.elapsed().as_secs_f64() * 1e3);
    }
    drop(stereo);

    let bare = Model::open(Path::new(model), card.clone(), Task::Stereo, &options)?;
    let (pw, ph) = Padding::for_card(width, height, &card.size).padded(width, height);
    let shape = vec![1, 3, i64::from(ph), i64::from(pw)];
    let tensor = vec![0.5f32; 3 * pw as usize * ph as usize];
    let names: Vec<&str> = ["left", "right"]
        .iter()
        .filter_map(|r| card.input(r))
        .collect();
    let inputs = || {
        names
            .iter()
            .map(|n| (*n, shape.clone(), tensor.clone()))
            .collect::<Vec<_>>()
    };
    // Copy the output out, as Python's run does into a numpy array.
    let copy_out = |_: &[i64], data: &[f32]| Ok(data.to_vec());
    bare.run(inputs(), copy_out)?; // warm-up
    let mut infer = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let inputs = inputs();
        let start = Instant::now();
        bare.run(inputs, copy_out)?;
        infer.push(start.elapsed().as_secs_f64() * 1e3);
    }
    let (full_median, full_min) = millis(&mut full);
    let (infer_median, infer_min) = millis(&mut infer);
    println!(
        "{{\"full_ms\": {full_median:.3}, \"full_min_ms\": {full_min:.3}, \"infer_ms\": {infer_median:.3}, \"infer_min_ms\": {infer_min:.3}, \"padded\": [{pw}, {ph}]}}"
    );
    Ok(())
}
