//! The dataset manifest (SPEC §3): the rig, the samples with one path per
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
    /// The encoding; only `carla-rgb` (SPEC §3) for now.
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
    /// Reads and parses a manifest (without schema or on-disk checks).
    pub fn load(path: &Path) -> Result<Manifest, DatasetError> {
        let text = std::fs::read_to_string(path).map_err(|source| DatasetError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|e| DatasetError::Manifest {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
    }

    /// Writes the manifest as pretty JSON, atomically.
    pub fn save(&self, path: &Path) -> Result<(), DatasetError> {
        // Serialising plain data structs with string keys cannot fail.
        let json = serde_json::to_string_pretty(self).expect("manifest serialises");
        mbs_core::atomic::write_bytes_atomic(path, format!("{json}\n").as_bytes())?;
        Ok(())
    }
}

/// The relative path that leads from folder `from` to folder `to` (both
/// made absolute first), e.g. `../data` from `/a/out` to `/a/data`.
pub fn relative_path(from: &Path, to: &Path) -> std::io::Result<PathBuf> {
    let from = std::path::absolute(from)?;
    let to = std::path::absolute(to)?;
    let from: Vec<_> = from.components().collect();
    let to: Vec<_> = to.components().collect();
    let common = from.iter().zip(&to).take_while(|(a, b)| a == b).count();
    let mut rel = PathBuf::new();
    for _ in common..from.len() {
        rel.push("..");
    }
    for c in &to[common..] {
        rel.push(c);
    }
    Ok(rel)
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
    fn relative_paths_between_folders() {
        assert_eq!(
            relative_path(Path::new("/a/out"), Path::new("/a/data/x")).unwrap(),
            Path::new("../data/x")
        );
        assert_eq!(
            relative_path(Path::new("/a"), Path::new("/a")).unwrap(),
            Path::new("")
        );
    }

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
}
