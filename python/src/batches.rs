//! `mbs._native.HostBatches`: the trainer's host batches for Python
//! (`mbs.torch.MultiBaselineDataset` wraps it), drawn and decoded by the
//! crate the trainer uses (`mbs-batch`), so a step's batch is the one
//! `mbs-tool train` draws for the same manifest, seed, batch size and crop.

use std::path::PathBuf;
use std::sync::Arc;

use mbs_batch::{
    AugmentConfig, HostBatch, MAX_BATCH_SIZE, MIN_CROP_SIDE, Stream, TrainingSamples, Triplet,
    load_batch, step_rng,
};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::integer::Integer;
use crate::{os_error, value_error};

/// The largest crop side (as the command line's images).
const MAX_CROP_SIDE: usize = crate::MAX_SIDE;

/// `trainer.augment`-style settings from JSON: unknown keys are refused
/// as `mbs-tool train --set` refuses them, missing ones take the paper's
/// values, and the ranges are checked.
fn augment_settings(json: &str) -> PyResult<AugmentConfig> {
    let given: serde_json::Map<String, serde_json::Value> = serde_json::from_str(json)
        .map_err(|e| value_error("augment", format!("not a dict of settings: {e}")))?;
    let known =
        serde_json::to_value(AugmentConfig::default()).map_err(|e| value_error("augment", e))?;
    let known: Vec<&String> = known
        .as_object()
        .map(|o| o.keys().collect())
        .unwrap_or_default();
    if let Some(unknown) = given.keys().find(|key| !known.contains(key)) {
        let known: Vec<&str> = known.iter().map(|k| k.as_str()).collect();
        return Err(value_error(
            "augment",
            format!("unknown key {unknown:?}; the keys are {}", known.join(", ")),
        ));
    }
    let augment: AugmentConfig = serde_json::from_value(serde_json::Value::Object(given))
        .map_err(|e| value_error("augment", format!("not augmentation settings: {e}")))?;
    augment.validate().map_err(|e| value_error("augment", e))?;
    Ok(augment)
}

/// The training batches of a run over the ``train`` samples of a manifest.
///
/// As ``mbs-tool train`` draws and decodes them;
/// ``mbs.torch.MultiBaselineDataset`` wraps it.
///
/// Parameters
/// ----------
/// manifest : str or os.PathLike
///     The manifest; its ``train`` samples are read, each at least the crop.
/// batch_size : int
///     Items per batch, 1 to 1024.
/// crop_height, crop_width : int
///     The crops' sides, 16 to 32768.
/// seed : int
///     The run's seed, 0 to ``2**64 - 1``.
/// augment_json : str, default "{}"
///     A JSON object of ``trainer.augment``-style keys; missing ones take the
///     paper's values, unknown ones are refused.
///
/// Raises
/// ------
/// OSError
///     The manifest cannot be used, or a sample is smaller than the crop (the
///     message names the manifest).
/// ValueError
///     A setting is out of range or unknown (the message begins with its
///     name).
/// TypeError
///     An integer argument is not an integer (the message begins with its
///     name).
#[pyclass(frozen, module = "mbs._native")]
pub struct HostBatches {
    manifest: PathBuf,
    samples: Arc<TrainingSamples>,
    batch_size: usize,
    crop: (usize, usize),
    seed: u64,
    augment: AugmentConfig,
}

#[pymethods]
impl HostBatches {
    /// Reads the manifest's `train` samples (every one at least the crop);
    /// `augment_json` holds `trainer.augment`-style keys, missing ones at
    /// the paper's values. (Python shows the struct's doc: pyo3 keeps no
    /// doc of `#[new]`.)
    #[new]
    #[pyo3(signature = (manifest, batch_size, crop_height, crop_width, seed, augment_json = "{}"))]
    fn new(
        py: Python<'_>,
        manifest: PathBuf,
        batch_size: Integer,
        crop_height: Integer,
        crop_width: Integer,
        seed: Integer,
        augment_json: &str,
    ) -> PyResult<Self> {
        let batch_size = batch_size.within("batch_size", 1..=MAX_BATCH_SIZE as i128)?;
        let crop_sides = MIN_CROP_SIDE as i128..=MAX_CROP_SIDE as i128;
        let crop_height = crop_height.within("crop height", crop_sides.clone())?;
        let crop_width = crop_width.within("crop width", crop_sides)?;
        let seed = seed.within("seed", 0..=i128::from(u64::MAX))?;
        let augment = augment_settings(augment_json)?;
        let crop = (crop_height, crop_width);
        let samples = py
            .detach(|| TrainingSamples::load(&manifest, crop))
            .map_err(|e| os_error(&manifest, e))?;
        Ok(HostBatches {
            manifest,
            samples: Arc::new(samples),
            batch_size,
            crop,
            seed,
            augment,
        })
    }

    /// Draws and decodes the batch of a step.
    ///
    /// Parameters
    /// ----------
    /// step : int
    ///     The step, 0 to ``2**32 - 1``.
    ///
    /// Returns
    /// -------
    /// dict
    ///     NumPy arrays and lists: the clean crops ``reference``,
    ///     ``student_target`` and ``teacher_target`` (``float32``,
    ///     ``[B, 3, H, W]`` in ``[0, 1]``), ``ratios`` (``float64``,
    ///     ``[B]``), ``triplets`` (``int64``, ``[B, 3]``: reference, student
    ///     and teacher view), ``windows`` (``int64``, ``[B, 2]``: top and
    ///     left of the crop), ``student_sides`` and ``teacher_sides``
    ///     (``"left"``/``"right"``), ``sample_ids``, ``skipped`` (unreadable
    ///     images met and replaced, each ``(path, error)``), and the
    ///     augmentation's draws: ``brightness``, ``contrast``,
    ///     ``saturation`` (``float32``, ``[B]``) and ``occlusion``
    ///     (``float32``, ``[B, 1, H, W]``, 1 where the target is erased).
    ///
    /// Raises
    /// ------
    /// OSError
    ///     The batch cannot be read (the message names the manifest).
    /// ValueError
    ///     ``step`` is out of range.
    /// TypeError
    ///     ``step`` is not an integer.
    fn batch<'py>(&self, py: Python<'py>, step: Integer) -> PyResult<Bound<'py, PyDict>> {
        let step: usize = step.within("step", 0..=i128::from(u32::MAX))?;
        let (batch, draws) = py
            .detach(|| {
                let batch = load_batch(&self.samples, self.batch_size, self.crop, self.seed, step)?;
                let mut rng = step_rng(self.seed, step, Stream::Augment);
                let draws = self
                    .augment
                    .draw(batch.len(), batch.height, batch.width, &mut rng);
                Ok::<_, mbs_batch::BatchError>((batch, draws))
            })
            .map_err(|e| os_error(&self.manifest, e))?;
        let HostBatch {
            height,
            width,
            reference,
            student_target,
            teacher_target,
            triplets,
            ratios,
            sample_ids,
            windows,
            skipped,
            ..
        } = batch;
        let items = triplets.len();
        let out = PyDict::new(py);
        let images = [3, height, width];
        let array = |values: Vec<f32>, shape: &[usize]| {
            let mut full = vec![items];
            full.extend_from_slice(shape);
            PyArray1::from_vec(py, values).reshape(full)
        };
        out.set_item("reference", array(reference, &images)?)?;
        out.set_item("student_target", array(student_target, &images)?)?;
        out.set_item("teacher_target", array(teacher_target, &images)?)?;
        out.set_item("ratios", PyArray1::from_vec(py, ratios))?;
        let corners: Vec<i64> = windows
            .iter()
            .flat_map(|w| [w.top as i64, w.left as i64])
            .collect();
        set_triplets_and_windows(&out, &triplets, corners)?;
        out.set_item("sample_ids", sample_ids)?;
        let skipped: Vec<(String, String)> = skipped
            .into_iter()
            .map(|(path, error)| (path.display().to_string(), error))
            .collect();
        out.set_item("skipped", skipped)?;
        out.set_item("brightness", PyArray1::from_vec(py, draws.brightness))?;
        out.set_item("contrast", PyArray1::from_vec(py, draws.contrast))?;
        out.set_item("saturation", PyArray1::from_vec(py, draws.saturation))?;
        out.set_item("occlusion", array(draws.occlusion, &[1, height, width])?)?;
        Ok(out)
    }
}

/// Sets `triplets` (the views of each item, `[B, 3]`), `windows` (each
/// crop's top left corner, `[B, 2]`, from `corners`), `student_sides` and
/// `teacher_sides` in a batch's dict `out`, in that order.
fn set_triplets_and_windows(
    out: &Bound<'_, PyDict>,
    triplets: &[Triplet],
    corners: Vec<i64>,
) -> PyResult<()> {
    let py = out.py();
    let items = triplets.len();
    let views: Vec<i64> = triplets
        .iter()
        .flat_map(|t| [t.reference, t.student, t.teacher].map(|v| v as i64))
        .collect();
    out.set_item(
        "triplets",
        PyArray1::from_vec(py, views).reshape([items, 3])?,
    )?;
    out.set_item(
        "windows",
        PyArray1::from_vec(py, corners).reshape([items, 2])?,
    )?;
    let side = |side: mbs_core::Side| match side {
        mbs_core::Side::Left => "left",
        mbs_core::Side::Right => "right",
    };
    let student: Vec<&str> = triplets.iter().map(|t| side(t.student_side())).collect();
    let teacher: Vec<&str> = triplets.iter().map(|t| side(t.teacher_side())).collect();
    out.set_item("student_sides", student)?;
    out.set_item("teacher_sides", teacher)?;
    Ok(())
}
