//! Scoring from Python: a prediction against its ground truth under any of
//! the named protocols, through `mbs-eval`, as `mbs-tool eval` scores it.
//! The report crosses as the command's JSON text.

use std::path::{Path, PathBuf};

use image::ImageBuffer;
use mbs_core::MaskImage;
use mbs_dataset::benchmark::Benchmark;
use mbs_dataset::ground_truth::GroundTruth;
use mbs_dataset::pairs::PairSource;
use mbs_eval::{
    Dataset, FrameList, Protocol, ProtocolReport, rules_for, score_predictions, score_truth,
};
use numpy::{PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::integer::Integer;
use crate::{check_sides, describe, float_map, os_error, value_error};

/// Scores a predicted disparity against its ground truth under a protocol.
///
/// As ``mbs-tool eval PRED --gt GT [--noc MASK] --protocol P --json``;
/// ``mbs.score`` parses what it returns.
///
/// Parameters
/// ----------
/// prediction : numpy.ndarray
///     The predicted disparity (``float32``, ``(H, W)``, ``inf`` where the
///     network gave none).
/// gt : numpy.ndarray
///     The ground truth (``float32``, ``(H, W)``, ``inf`` where unknown).
/// noc : numpy.ndarray, optional
///     The non-occluded mask (``uint8``, ``(H, W)``, non-zero where the
///     pixel is visible in the other view); NOC and OCC need it.
/// protocol : str, default "s3"
///     ``pixels``, ``s3``, ``raft-stereo``, ``igev-stereo``, ``kitti``,
///     ``eth3d`` or ``middlebury`` (docs/evaluation.md).
/// dataset : str, default "other"
///     Whose rules the protocol applies: ``kitti2015``, ``kitti2012``,
///     ``middlebury``, ``eth3d``, ``drivingstereo``, ``sceneflow`` or
///     ``other``.
/// disparity_bound : int, optional
///     The scene's disparity bound (Middlebury's ``ndisp``).
/// thresholds : list of float, optional
///     Out-x thresholds in pixels (default: 1, 2, 3 under ``pixels``,
///     the protocol's own otherwise).
/// name : str, default "image"
///     The image's name in the report.
///
/// Returns
/// -------
/// str
///     The command's report as JSON text.
///
/// Raises
/// ------
/// ValueError
///     An unknown protocol or dataset, a protocol with no rules for the
///     dataset, a wrong array, a ground truth with no valid pixel, or a
///     prediction the rules cannot score (the message names the argument).
#[pyfunction]
#[pyo3(signature = (
    prediction, gt, *, noc = None, protocol = "s3", dataset = "other",
    disparity_bound = None, thresholds = None, name = "image"
))]
#[allow(clippy::too_many_arguments)] // the keyword arguments of `mbs.score`
pub fn score_json(
    py: Python<'_>,
    prediction: &Bound<'_, PyAny>,
    gt: &Bound<'_, PyAny>,
    noc: Option<&Bound<'_, PyAny>>,
    protocol: &str,
    dataset: &str,
    disparity_bound: Option<Integer>,
    thresholds: Option<Vec<f32>>,
    name: &str,
) -> PyResult<String> {
    let protocol: Protocol = protocol.parse().map_err(|e| value_error("protocol", e))?;
    let dataset: Dataset = dataset.parse().map_err(|e| value_error("dataset", e))?;
    let thresholds = checked_thresholds(thresholds)?;
    let rules =
        rules_for(protocol, dataset, &thresholds).map_err(|e| value_error("protocol", e))?;
    let disparity_bound = disparity_bound
        .map(|bound| bound.within("disparity_bound", 1..=i128::from(u32::MAX)))
        .transpose()?;
    let prediction = float_map("prediction", prediction)?;
    let truth = GroundTruth {
        disparity: float_map("gt", gt)?,
        noc: noc.map(|mask| mask_image("noc", mask)).transpose()?,
    };
    let score = py
        .detach(|| {
            score_truth(
                &truth,
                Path::new("gt"),
                &prediction,
                Path::new("prediction"),
                disparity_bound,
                &rules,
            )
        })
        .map_err(|e| PyErr::new::<pyo3::exceptions::PyValueError, _>(e.to_string()))?;
    let mut report = ProtocolReport::new(rules, vec![(name.to_string(), score)]).json();
    report["unscored"] = serde_json::json!([]);
    Ok(report.to_string())
}

/// A `uint8` HxW array as a mask.
fn mask_image(name: &str, value: &Bound<'_, PyAny>) -> PyResult<MaskImage> {
    let array = value.cast::<PyArray2<u8>>().map_err(|_| {
        value_error(
            name,
            format!("expected a uint8 HxW array, got {}", describe(value)),
        )
    })?;
    let [height, width] = [array.shape()[0], array.shape()[1]];
    check_sides(name, height, width)?;
    let values: Vec<u8> = array.readonly().as_array().iter().copied().collect();
    ImageBuffer::from_raw(width as u32, height as u32, values)
        .ok_or_else(|| value_error(name, "its data does not match its shape"))
}

/// Scores a folder of predictions against a benchmark folder's ground truth.
///
/// As ``mbs-tool eval PREDICTIONS --BENCHMARK FOLDER [--frames FILE]
/// --protocol P --json``; ``mbs.score_folder`` parses what it returns.
///
/// Parameters
/// ----------
/// predictions : str or os.PathLike
///     The folder of predictions, one ``<frame>.pfm``, ``.png`` or ``.exr``
///     per pair (KITTI ``000000_10``, a Middlebury or ETH3D scene...).
/// benchmark : str
///     The folder's layout, as ``eval``'s flag names it: ``kitti``,
///     ``middlebury``, ``eth3d``, ``drivingstereo`` or ``sceneflow``.
/// folder : str or os.PathLike
///     The benchmark folder (e.g. ``kitti2015/training``,
///     ``MiddEval3/trainingH``).
/// protocol : str, default "s3"
///     ``pixels``, ``s3``, ``raft-stereo``, ``igev-stereo``, ``kitti``,
///     ``eth3d`` or ``middlebury``.
/// frames : list of str, optional
///     Score only these frames (each must be one of the folder's).
/// thresholds : list of float, optional
///     Out-x thresholds in pixels (default: 1, 2, 3 under ``pixels``,
///     the protocol's own otherwise).
///
/// Returns
/// -------
/// str
///     The command's report as JSON text, with ``failed``: each image that
///     could not be scored, as ``[name, reason]``.
///
/// Raises
/// ------
/// ValueError
///     An unknown benchmark or protocol, a protocol with no rules for the
///     benchmark, an empty frame list, or wrong thresholds.
/// OSError
///     The folder is off its layout, a listed frame is not one of its
///     frames, or no image could be scored.
#[pyfunction]
#[pyo3(signature = (predictions, benchmark, folder, *, protocol = "s3", frames = None, thresholds = None))]
pub fn score_folder_json(
    py: Python<'_>,
    predictions: PathBuf,
    benchmark: &str,
    folder: PathBuf,
    protocol: &str,
    frames: Option<Vec<String>>,
    thresholds: Option<Vec<f32>>,
) -> PyResult<String> {
    let benchmark: Benchmark = benchmark.parse().map_err(|e| value_error("benchmark", e))?;
    let protocol: Protocol = protocol.parse().map_err(|e| value_error("protocol", e))?;
    let thresholds = checked_thresholds(thresholds)?;
    let rules = rules_for(protocol, benchmark.dataset(&folder), &thresholds)
        .map_err(|e| value_error("protocol", e))?;
    let frames = frames
        .map(|names| FrameList::from_names(PathBuf::from("frames"), names))
        .transpose()
        .map_err(|e| value_error("frames", e))?;
    let source = PairSource::Benchmark {
        benchmark,
        dir: folder.clone(),
    };
    let scores = py
        .detach(|| score_predictions(&source, &predictions, frames.as_ref(), &rules, &|_| {}))
        .map_err(|e| os_error(&folder, error_chain(&e)))?;
    let failed: Vec<(String, String)> = scores
        .failed
        .iter()
        .map(|(name, error)| (name.clone(), error_chain(error)))
        .collect();
    let Some(mut report) = scores.json() else {
        let reasons: Vec<String> = failed.iter().map(|(n, e)| format!("{n}: {e}")).collect();
        return Err(os_error(
            &predictions,
            format!("no image could be scored: {}", reasons.join("; ")),
        ));
    };
    report["failed"] = serde_json::json!(failed);
    Ok(report.to_string())
}

/// Out-x thresholds as given (none: the protocol's), each a positive
/// number of pixels.
fn checked_thresholds(thresholds: Option<Vec<f32>>) -> PyResult<Vec<f32>> {
    let thresholds = thresholds.unwrap_or_default();
    if let Some(bad) = thresholds.iter().find(|t| !(t.is_finite() && **t > 0.0)) {
        return Err(value_error(
            "thresholds",
            format!("{bad} is not a positive number of pixels"),
        ));
    }
    Ok(thresholds)
}

/// An error and its causes joined by `: `, a cause its message already
/// ends with left out (as the command prints them).
fn error_chain(error: &(dyn std::error::Error + 'static)) -> String {
    let mut text = error.to_string();
    let mut cause = error.source();
    while let Some(here) = cause {
        let part = here.to_string();
        if !text.ends_with(&part) {
            text = format!("{text}: {part}");
        }
        cause = here.source();
    }
    text
}
