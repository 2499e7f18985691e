//! The agreement check: an exported model through ONNX Runtime beside
//! mbs's own forward pass on one real pair, as `predict --model --card`
//! and `predict --weights` run them.

use std::time::Instant;

use burn::tensor::Device;
use mbs_core::{RgbImage, Side};
use mbs_infer::StereoMatcher;
use mbs_infer::onnx::stereo::OnnxStereo;
use mbs_nets::Backbone;
use mbs_nets::inference::predict_image;

/// The largest differences an export may have from mbs's forward pass, in
/// pixels of disparity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Mean absolute difference.
    pub mean: f32,
    /// Largest absolute difference.
    pub largest: f32,
}

impl Default for Tolerance {
    /// 1e-3 px mean and 1e-2 px largest: the f32 rounding of two
    /// implementations of the same operations, carried through the
    /// iterations (measured: below 1e-4 px on every network tested).
    fn default() -> Self {
        Self {
            mean: 1e-3,
            largest: 1e-2,
        }
    }
}

/// How an export agreed with mbs on the check pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Agreement {
    /// Largest absolute difference, pixels.
    pub largest: f32,
    /// Mean absolute difference, pixels.
    pub mean: f32,
    /// Pixels compared: those mbs predicts at 0 or more (`predict --model`
    /// marks a negative disparity invalid, as for any ONNX model).
    pub compared: usize,
    /// Pixels of the pair.
    pub pixels: usize,
    /// Seconds of mbs's forward pass (CPU).
    pub mbs_seconds: f64,
    /// Seconds of the ONNX Runtime run.
    pub onnx_seconds: f64,
}

impl Agreement {
    /// Whether both differences are within `tolerance`.
    pub fn within(&self, tolerance: &Tolerance) -> bool {
        self.mean <= tolerance.mean && self.largest <= tolerance.largest
    }
}

/// Why the check could not run.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    /// mbs's forward pass failed.
    #[error("mbs's forward pass on the check pair: {0}")]
    Mbs(String),
    /// ONNX Runtime's run failed.
    #[error("ONNX Runtime on the check pair: {0}")]
    Onnx(String),
    /// A pixel mbs predicts at 0 or more came back invalid.
    #[error("the export lost pixel {0}: mbs predicts {1} px there")]
    Lost(usize, f32),
}

/// Runs `network` and `onnx` on the pair (already at the export's size)
/// and measures their differences.
pub fn compare<B: Backbone>(
    network: &B,
    onnx: &OnnxStereo,
    left: &RgbImage,
    right: &RgbImage,
) -> Result<Agreement, CheckError> {
    let start = Instant::now();
    let ours = predict_image(network, left, right, Side::Right, &Device::flex())
        .map_err(|e| CheckError::Mbs(e.to_string()))?;
    let mbs_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let theirs = onnx
        .predict(left, right)
        .map_err(|e| CheckError::Onnx(e.to_string()))?;
    let onnx_seconds = start.elapsed().as_secs_f64();
    let (mut largest, mut sum, mut compared) = (0.0f32, 0.0f64, 0usize);
    for (i, (a, b)) in ours.iter().zip(theirs.disparity.iter()).enumerate() {
        if *a < 0.0 {
            continue;
        }
        if !b.is_finite() {
            return Err(CheckError::Lost(i, *a));
        }
        let difference = (a - b).abs();
        largest = largest.max(difference);
        sum += f64::from(difference);
        compared += 1;
    }
    Ok(Agreement {
        largest,
        mean: (sum / compared.max(1) as f64) as f32,
        compared,
        pixels: ours.len(),
        mbs_seconds,
        onnx_seconds,
    })
}
