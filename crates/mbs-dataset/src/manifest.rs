//! The dataset manifest (conventions §3): the rig, the samples with one path per
//! view and optional depth, ground truth and masks, and the provenance of
//! synthesised data. Paths are relative to the manifest's folder. The JSON
//! Schema in `schemas/manifest.schema.json` describes the same model.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use mbs_core::Rig;
use serde::{Deserialize, Serialize};

use crate::error::DatasetError;

/// The value of the manifest's `format` field.
pub const FORMAT: &str = "mbs-manifest/1";

/// A whole dataset description.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Always [`FORMAT`].
    pub format: String,
    /// A short human-readable name of the dataset.
    pub name: String,
    /// The camera rig shared by all samples.
    pub rig: Rig,
    /// How depth images are encoded, when samples carry depth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth: Option<DepthInfo>,
    /// The samples (one multi-view capture each).
    pub samples: Vec<Sample>,
    /// Which tool and settings produced (or synthesised) the data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<Provenance>,
}

/// How the depth images of a dataset are encoded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DepthInfo {
    /// The encoding; only `carla-rgb` (conventions §3) for now.
    pub encoding: DepthEncoding,
    /// The camera whose depth is given.
    pub camera: usize,
    /// Depth beyond this (metres) is invalid for disparity.
    pub max_depth_m: f64,
}

/// Depth image encodings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum DepthEncoding {
    /// CARLA's 8-bit RGB encoding, `1000 (R + 256 G + 65536 B) / (256^3 - 1)` m.
    #[serde(rename = "carla-rgb")]
    CarlaRgb,
}

/// Which split a sample belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    /// Training data.
    Train,
    /// Validation data.
    Val,
    /// Held-out test data (MBS20K: Town10).
    Test,
}

/// One multi-view capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sample {
    /// Unique id, e.g. `Town01/ClearNoon/000123`.
    pub id: String,
    /// The split.
    pub split: Split,
    /// CARLA town (MBS20K).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub town: Option<String>,
    /// CARLA weather (MBS20K).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weather: Option<String>,
    /// Sequence or drive name (KITTI and other captures).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sequence: Option<String>,
    /// One image path per camera, left to right.
    pub views: Vec<String>,
    /// Depth image of camera `depth.camera` (see [`DepthInfo`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth: Option<String>,
    /// Ground-truth disparity for camera pairs.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ground_truth: Vec<PairGroundTruth>,
    /// Per-view masks of synthesised pixels (255 = synthesised), `None`
    /// for captured views.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub synthesized_masks: Vec<Option<String>>,
    /// SHA-256 (lowercase hex) of some of this sample's files, by path.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub sha256: BTreeMap<String, String>,
    /// `(width, height)` of this sample's images when it differs from the
    /// rig's (KITTI frames vary by a few pixels).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_size: Option<(u32, u32)>,
}

impl Sample {
    /// The `(width, height)` of this sample's images.
    pub fn size(&self, rig: &Rig) -> (u32, u32) {
        self.image_size.unwrap_or((rig.width, rig.height))
    }
}

/// Ground-truth disparity of one ordered camera pair.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairGroundTruth {
    /// The reference camera (the disparity lives on its grid).
    pub reference: usize,
    /// The target camera.
    pub target: usize,
    /// A float map (PFM, EXR or KITTI 16-bit PNG).
    pub disparity: String,
    /// The pair's disparity is `scale` times the file's values (lets pairs
    /// of one reference share a one-baseline file).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub scale: f64,
    /// Mask of reference pixels not visible in the target (255 = occluded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occlusion: Option<String>,
}

fn one() -> f64 {
    1.0
}

fn is_one(v: &f64) -> bool {
    *v == 1.0
}

/// Which tool and settings produced the data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    /// The producing command, e.g. `mbs-tool synth`.
    pub tool: String,
    /// Its version.
    pub version: String,
    /// Its settings, free-form.
    #[serde(default)]
    pub settings: serde_json::Value,
}

impl Sample {
    /// Every file this sample refers to, with a short label of its role.
    pub fn files(&self) -> Vec<(FileRole, &str)> {
        let mut files: Vec<(FileRole, &str)> = self
            .views
            .iter()
            .map(|v| (FileRole::View, v.as_str()))
            .collect();
        files.extend(self.depth.iter().map(|d| (FileRole::Depth, d.as_str())));
        for gt in &self.ground_truth {
            files.push((FileRole::Disparity, gt.disparity.as_str()));
            files.extend(gt.occlusion.iter().map(|o| (FileRole::Mask, o.as_str())));
        }
        files.extend(
            self.synthesized_masks
                .iter()
                .flatten()
                .map(|m| (FileRole::Mask, m.as_str())),
        );
        files
    }
}

/// What a file of a sample is for; decides how it is checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileRole {
    /// A camera image (8-bit colour).
    View,
    /// A CARLA depth image (8-bit RGB).
    Depth,
    /// A disparity float map.
    Disparity,
    /// An 8-bit mask.
    Mask,
}

impl Manifest {
    /// Reads a manifest and checks it against the schema (which includes
    /// the confined-name rule for paths and ids, see
    /// [`mbs_core::confine`]) and against the rules the schema cannot
    /// state (unique ids), so that every command reads the same model.
    /// On-disk checks are `validate`'s.
    pub fn load(path: &Path) -> Result<Manifest, DatasetError> {
        let text = mbs_core::regular::read_text(path)?;
        let document: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| manifest_error(path, format!("not valid JSON: {e}")))?;
        Manifest::from_document(path, document)
    }

    /// [`Manifest::load`] for an already parsed document read from `path`.
    pub fn from_document(
        path: &Path,
        mut document: serde_json::Value,
    ) -> Result<Manifest, DatasetError> {
        let issues = crate::schema::manifest_schema_issues(&document);
        if let Some(first) = issues.first() {
            return Err(manifest_error(
                path,
                format!(
                    "{} schema problem(s), the first at {}: {} (`mbs-tool validate` lists them all)",
                    issues.len(),
                    if first.pointer.is_empty() {
                        "/"
                    } else {
                        &first.pointer
                    },
                    first.message
                ),
            ));
        }
        integral_numbers_as_integers(&mut document);
        let manifest: Manifest =
            serde_json::from_value(document).map_err(|e| manifest_error(path, e.to_string()))?;
        if let Some(id) = manifest.duplicate_id() {
            return Err(manifest_error(
                path,
                format!("sample id {id:?} appears more than once (ids must be unique)"),
            ));
        }
        Ok(manifest)
    }

    /// The first sample id that appears twice, if any.
    pub fn duplicate_id(&self) -> Option<&str> {
        let mut seen = std::collections::HashSet::new();
        self.samples
            .iter()
            .map(|s| s.id.as_str())
            .find(|id| !seen.insert(*id))
    }

    /// Writes the manifest as pretty JSON, atomically.
    pub fn save(&self, path: &Path) -> Result<(), DatasetError> {
        // Serialising plain data structs with string keys cannot fail.
        let json = serde_json::to_string_pretty(self).expect("manifest serialises");
        mbs_core::atomic::write_bytes_atomic(path, format!("{json}\n").as_bytes())?;
        Ok(())
    }
}

fn manifest_error(path: &Path, message: String) -> DatasetError {
    DatasetError::Manifest {
        path: path.to_path_buf(),
        message,
    }
}

/// Rewrites numbers with no fractional part (`1.0`) as integers, as JSON
/// Schema's `integer` counts them, so that the model reads every document
/// the schema accepts. Float fields read integers unchanged.
pub fn integral_numbers_as_integers(value: &mut serde_json::Value) {
    use serde_json::Value;
    match value {
        Value::Number(n) => {
            if let Some(f) = n.as_f64().filter(|f| n.is_f64() && f.fract() == 0.0) {
                if f >= 0.0 && f < u64::MAX as f64 {
                    *n = (f as u64).into();
                } else if f < 0.0 && f >= i64::MIN as f64 {
                    *n = (f as i64).into();
                }
            }
        }
        Value::Array(items) => items.iter_mut().for_each(integral_numbers_as_integers),
        Value::Object(fields) => fields.values_mut().for_each(integral_numbers_as_integers),
        _ => {}
    }
}

impl Manifest {
    /// Prefixes every file path with `prefix` (for a manifest moved to
    /// another folder than the one its paths were relative to).
    pub fn rebase(&mut self, prefix: &Path) {
        if prefix.as_os_str().is_empty() {
            return;
        }
        let join = |p: &mut String| *p = prefix.join(&*p).to_string_lossy().into_owned();
        for s in &mut self.samples {
            s.views.iter_mut().for_each(join);
            s.depth.iter_mut().for_each(join);
            for gt in &mut s.ground_truth {
                join(&mut gt.disparity);
                gt.occlusion.iter_mut().for_each(join);
            }
            s.synthesized_masks.iter_mut().flatten().for_each(join);
            s.sha256 = std::mem::take(&mut s.sha256)
                .into_iter()
                .map(|(mut k, v)| {
                    join(&mut k);
                    (k, v)
                })
                .collect();
        }
    }
}

/// The folder of the manifest file `manifest_path`, which its paths are
/// relative to (`.` for a bare file name).
pub fn folder(manifest_path: &Path) -> PathBuf {
    match manifest_path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Resolves a manifest-relative path against the manifest's folder.
pub fn resolve(manifest_path: &Path, relative: &str) -> PathBuf {
    manifest_path
        .parent()
        .unwrap_or(Path::new(""))
        .join(relative)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_json_and_omits_defaults() {
        let sample = Sample {
            id: "Town01/ClearNoon/000001".into(),
            split: Split::Train,
            town: Some("Town01".into()),
            weather: Some("ClearNoon".into()),
            sequence: None,
            views: vec!["a.png".into(), "b.png".into()],
            depth: None,
            ground_truth: vec![PairGroundTruth {
                reference: 0,
                target: 1,
                disparity: "d.pfm".into(),
                scale: 1.0,
                occlusion: None,
            }],
            synthesized_masks: vec![],
            sha256: BTreeMap::new(),
            image_size: None,
        };
        let manifest = Manifest {
            format: FORMAT.into(),
            name: "t".into(),
            rig: Rig::centred(2, 0.5, 480.0, 4, 3),
            depth: None,
            samples: vec![sample],
            provenance: None,
        };
        let json = serde_json::to_value(&manifest).unwrap();
        assert!(json["samples"][0].get("sha256").is_none());
        assert!(json["samples"][0]["ground_truth"][0].get("scale").is_none());
        let back: Manifest = serde_json::from_value(json).unwrap();
        assert_eq!(back, manifest);
    }

    fn write_manifest(dir: &Path, samples: serde_json::Value) -> PathBuf {
        let doc = serde_json::json!({
            "format": FORMAT,
            "name": "t",
            "rig": {"num_views": 2, "baseline_m": 0.5, "focal_px": 480.0, "cx": 1.5, "cy": 1.0, "width": 4, "height": 3},
            "samples": samples
        });
        let path = dir.join("manifest.json");
        std::fs::write(&path, doc.to_string()).unwrap();
        path
    }

    #[test]
    fn load_reads_what_the_schema_accepts_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let views = serde_json::json!(["a0.png", "a1.png"]);
        // `1.0` is an integer to JSON Schema, so the model reads it too.
        let path = write_manifest(
            dir.path(),
            serde_json::json!([{"id": "a", "split": "train", "views": views,
                "ground_truth": [{"reference": 0.0, "target": 1.0, "disparity": "d.pfm"}]}]),
        );
        let manifest = Manifest::load(&path).unwrap();
        assert_eq!(manifest.samples[0].ground_truth[0].target, 1);
        // Escaping paths and ids, duplicate ids and a bad rig are refused, naming the place.
        for (samples, expected) in [
            (
                serde_json::json!([{"id": "../x", "split": "train", "views": views}]),
                "/samples/0/id",
            ),
            (
                serde_json::json!([{"id": "a", "split": "train", "views": ["../a0.png", "a1.png"]}]),
                "/samples/0/views/0",
            ),
            (
                serde_json::json!([{"id": "a", "split": "train", "views": views},
                                   {"id": "a", "split": "val", "views": views}]),
                "sample id \"a\" appears more than once",
            ),
        ] {
            let path = write_manifest(dir.path(), samples);
            let err = Manifest::load(&path).unwrap_err().to_string();
            assert!(
                err.contains("manifest.json") && err.contains(expected),
                "{err}"
            );
        }
        let path = dir.path().join("manifest.json");
        let text = std::fs::read_to_string(&path)
            .unwrap()
            .replace("480.0", "-5");
        std::fs::write(&path, text).unwrap();
        let err = Manifest::load(&path).unwrap_err().to_string();
        assert!(err.contains("/rig/focal_px"), "{err}");
    }
}
