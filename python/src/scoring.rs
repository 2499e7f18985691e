//! Scoring from Python: a prediction against its ground truth under any of
//! the named protocols, through `mbs-eval`, as `mbs-tool eval` scores it.
//! The report crosses as the command's JSON text.

use std::path::Path;

use image::ImageBuffer;
use mbs_core::MaskImage;
use mbs_dataset::ground_truth::GroundTruth;
use mbs_eval::{Dataset, Protocol, ProtocolReport, rules_for, score_truth};
use numpy::{PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::integer::Integer;
use crate::{check_sides, describe, float_map, value_error};

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
    let thresholds = thresholds.unwrap_or_default();
    if let Some(bad) = thresholds.iter().find(|t| !(t.is_finite() && **t > 0.0)) {
        return Err(value_error(
            "thresholds",
            format!("{bad} is not a positive number of pixels"),
        ));
    }
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
