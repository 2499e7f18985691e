//! Writes synthetic scenes as a dataset in the MBS20K layout
//! (`<root>/<Town>/<Weather>/<frame>/rgb_k.png, depth_0.png`) with a
//! manifest, plus what no real dataset has: exact ground truth for every
//! camera pair (`gt/disp_k.pfm`, the one-baseline disparity of camera k, and
//! `gt/occ_r_t.png`, 255 where a pixel of r is not visible from t).
//!
//! Like MBS20K, each scene (a town's frame) is rendered under every weather:
//! the geometry is the same, only the light changes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use mbs_core::Rig;
use mbs_core::formats::{carla, pfm, rgb};
use mbs_dataset::manifest::{
    DepthEncoding, DepthInfo, FORMAT, Manifest, PairGroundTruth, Provenance, Sample, Split,
};
use mbs_dataset::{DatasetError, checksum::sha256_file, mbs20k};
use serde::Serialize;

use crate::{
    RenderOptions, Scene, SceneConfig, Weather, occlusion_mask, one_step_disparity, render,
};

/// What to synthesise.
#[derive(Debug, Clone, Serialize)]
pub struct DatasetSpec {
    /// The camera rig.
    pub rig: Rig,
    /// Town names (folder names); each gets its own scenes.
    pub towns: Vec<String>,
    /// Weathers every scene is rendered under.
    pub weathers: Vec<Weather>,
    /// Scenes (frames) per town.
    pub frames: usize,
    /// Master seed: scene `i` of town `t` uses a seed derived from it.
    pub seed: u64,
    /// Towns whose samples form the test split.
    pub test_towns: Vec<String>,
    /// Scene generation parameters.
    pub scene: SceneConfig,
    /// Samples per pixel along each axis.
    pub supersample: u32,
    /// Depth beyond this is invalid for disparity (recorded in the manifest).
    pub max_depth_m: f64,
    /// Record the SHA-256 of every file in the manifest.
    pub checksums: bool,
}

/// One scene to render: a town's frame, under every weather.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Index of the town in [`DatasetSpec::towns`].
    pub town: usize,
    /// Frame number within the town.
    pub index: usize,
}

/// The file name of the one-baseline GT disparity of camera `k`.
pub fn disparity_file(k: usize) -> String {
    format!("gt/disp_{k}.pfm")
}

/// The file name of the occlusion mask of pair (`r`, `t`).
pub fn occlusion_file(r: usize, t: usize) -> String {
    format!("gt/occ_{r}_{t}.png")
}

impl DatasetSpec {
    /// Every frame, in a fixed order.
    pub fn frames(&self) -> Vec<Frame> {
        (0..self.towns.len())
            .flat_map(|town| (0..self.frames).map(move |index| Frame { town, index }))
            .collect()
    }

    /// The seed of a frame's scene, derived from the master seed.
    pub fn scene_seed(&self, frame: &Frame) -> u64 {
        // SplitMix64 finaliser: distinct, well-mixed seeds for neighbouring frames.
        let mut z = self
            .seed
            .wrapping_add((frame.town as u64) << 32)
            .wrapping_add(frame.index as u64)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// The sample id (and folder, relative to the root) of a frame under a weather.
    pub fn sample_id(&self, frame: &Frame, weather: Weather) -> String {
        format!(
            "{}/{}/{:06}",
            self.towns[frame.town],
            weather.name(),
            frame.index
        )
    }

    /// Every file `frame` writes under `root`, for every weather.
    pub fn frame_outputs(&self, root: &Path, frame: &Frame) -> Vec<PathBuf> {
        let files = self.sample_files();
        self.weathers
            .iter()
            .flat_map(|&w| {
                let dir = root.join(self.sample_id(frame, w));
                files.iter().map(move |f| dir.join(f)).collect::<Vec<_>>()
            })
            .collect()
    }

    /// Every file of one sample, relative to its folder.
    fn sample_files(&self) -> Vec<String> {
        let n = self.rig.num_views;
        let mut files: Vec<String> = (0..n).map(mbs20k::view_file).collect();
        files.push(mbs20k::DEPTH_FILE.to_string());
        files.extend((0..n).map(disparity_file));
        for r in 0..n {
            files.extend((0..n).filter(|&t| t != r).map(|t| occlusion_file(r, t)));
        }
        files
    }

    /// True when every file of the frame exists under every weather (each
    /// file is written atomically, so existing files are complete).
    pub fn is_complete(&self, root: &Path, frame: &Frame) -> bool {
        let files = self.sample_files();
        self.weathers.iter().all(|&w| {
            let dir = root.join(self.sample_id(frame, w));
            files.iter().all(|f| dir.join(f).is_file())
        })
    }

    /// Renders one frame under every weather and writes its files.
    pub fn write_frame(&self, root: &Path, frame: &Frame) -> Result<(), DatasetError> {
        let n = self.rig.num_views;
        let scene = Scene::generate(self.scene_seed(frame), &self.scene);
        let mut ground_truth_written: Option<PathBuf> = None;
        for &weather in &self.weathers {
            let dir = root.join(self.sample_id(frame, weather));
            let options = RenderOptions {
                supersample: self.supersample,
                weather,
                ..RenderOptions::default()
            };
            let out = render(&scene, &self.rig, &options);
            for (k, view) in out.views.iter().enumerate() {
                rgb::write_rgb_png(&dir.join(mbs20k::view_file(k)), view)?;
            }
            if let Some(first) = &ground_truth_written {
                // Geometry does not depend on the weather: copy the first weather's files.
                copy_ground_truth(first, &dir, self)?;
                continue;
            }
            rgb::write_rgb_png(
                &dir.join(mbs20k::DEPTH_FILE),
                &carla::encode_depth(&out.depth[0]),
            )?;
            for (k, depth) in out.depth.iter().enumerate() {
                let disparity = one_step_disparity(depth, &self.rig);
                pfm::write_pfm_grey(
                    &dir.join(disparity_file(k)),
                    &disparity,
                    pfm::Endian::Little,
                )?;
            }
            for r in 0..n {
                for t in (0..n).filter(|&t| t != r) {
                    let mask = occlusion_mask(&scene, &self.rig, r, t);
                    rgb::write_mask_png(&dir.join(occlusion_file(r, t)), &mask)?;
                }
            }
            ground_truth_written = Some(dir);
        }
        Ok(())
    }

    /// The manifest of the whole dataset (files must exist when checksums are on).
    pub fn manifest(&self, root: &Path) -> Result<Manifest, DatasetError> {
        let mut samples = Vec::new();
        for frame in self.frames() {
            for &weather in &self.weathers {
                samples.push(self.manifest_sample(root, &frame, weather)?);
            }
        }
        Ok(Manifest {
            format: FORMAT.into(),
            name: "mbs-synth".into(),
            rig: self.rig,
            depth: Some(DepthInfo {
                encoding: DepthEncoding::CarlaRgb,
                camera: 0,
                max_depth_m: self.max_depth_m,
            }),
            samples,
            provenance: Some(Provenance {
                tool: "mbs-tool synth".into(),
                version: env!("CARGO_PKG_VERSION").into(),
                // Plain data with string keys serialises.
                settings: serde_json::to_value(self).expect("spec serialises"),
            }),
        })
    }

    /// The manifest's entry for one frame under one weather.
    fn manifest_sample(
        &self,
        root: &Path,
        frame: &Frame,
        weather: Weather,
    ) -> Result<Sample, DatasetError> {
        let n = self.rig.num_views;
        let id = self.sample_id(frame, weather);
        let town = &self.towns[frame.town];
        Ok(Sample {
            views: (0..n)
                .map(|k| format!("{id}/{}", mbs20k::view_file(k)))
                .collect(),
            depth: Some(format!("{id}/{}", mbs20k::DEPTH_FILE)),
            split: if self.test_towns.contains(town) {
                Split::Test
            } else {
                Split::Train
            },
            town: Some(town.clone()),
            weather: Some(weather.name().to_string()),
            sequence: None,
            ground_truth: pair_ground_truth(n, &id),
            synthesized_masks: Vec::new(),
            sha256: self.sample_checksums(root, &id)?,
            image_size: None,
            id,
        })
    }

    /// The SHA-256 of each of sample `id`'s files under `root`, by path
    /// relative to it; empty when checksums are off.
    fn sample_checksums(
        &self,
        root: &Path,
        id: &str,
    ) -> Result<BTreeMap<String, String>, DatasetError> {
        let mut sha256 = BTreeMap::new();
        if self.checksums {
            for file in self.sample_files() {
                let rel = format!("{id}/{file}");
                let digest = sha256_file(&root.join(&rel)).map_err(|source| DatasetError::Io {
                    path: root.join(&rel),
                    source,
                })?;
                sha256.insert(rel, digest);
            }
        }
        Ok(sha256)
    }
}

/// The ground truth of every ordered pair of an `n`-view sample `id`: the
/// reference view's disparity scaled by the baseline ratio, and the pair's
/// occlusion mask.
fn pair_ground_truth(n: usize, id: &str) -> Vec<PairGroundTruth> {
    (0..n)
        .flat_map(|r| (0..n).filter(move |&t| t != r).map(move |t| (r, t)))
        .map(|(r, t)| PairGroundTruth {
            reference: r,
            target: t,
            disparity: format!("{id}/{}", disparity_file(r)),
            scale: r.abs_diff(t) as f64,
            occlusion: Some(format!("{id}/{}", occlusion_file(r, t))),
        })
        .collect()
}

fn copy_ground_truth(from: &Path, to: &Path, spec: &DatasetSpec) -> Result<(), DatasetError> {
    let views: Vec<String> = (0..spec.rig.num_views).map(mbs20k::view_file).collect();
    for file in spec
        .sample_files()
        .into_iter()
        .filter(|f| !views.contains(f))
    {
        let bytes = mbs_core::regular::read_bytes(&from.join(&file))?;
        mbs_core::atomic::write_bytes_atomic(&to.join(&file), &bytes)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> DatasetSpec {
        let rig = Rig::centred(3, 0.5, 30.0, 40, 24);
        DatasetSpec {
            rig,
            towns: vec!["Town01".into(), "Town10".into()],
            weathers: vec![Weather::ClearNoon, Weather::ClearNight],
            frames: 1,
            seed: 3,
            test_towns: vec!["Town10".into()],
            scene: SceneConfig::centred_on(&rig),
            supersample: 1,
            max_depth_m: 200.0,
            checksums: true,
        }
    }

    #[test]
    fn writes_layout_ground_truth_and_a_valid_manifest() {
        let dir = tempfile::tempdir().unwrap();
        let spec = spec();
        for frame in spec.frames() {
            assert!(!spec.is_complete(dir.path(), &frame));
            spec.write_frame(dir.path(), &frame).unwrap();
            assert!(spec.is_complete(dir.path(), &frame));
        }
        let manifest = spec.manifest(dir.path()).unwrap();
        assert_eq!(manifest.samples.len(), 4);
        let test = manifest
            .samples
            .iter()
            .filter(|s| s.split == Split::Test)
            .count();
        assert_eq!(test, 2);
        let sample = &manifest.samples[0];
        assert_eq!(sample.id, "Town01/ClearNoon/000000");
        assert_eq!(sample.ground_truth.len(), 6);
        let far_pair = sample
            .ground_truth
            .iter()
            .find(|g| (g.reference, g.target) == (2, 0))
            .unwrap();
        assert_eq!(far_pair.scale, 2.0);
        assert_eq!(far_pair.disparity, "Town01/ClearNoon/000000/gt/disp_2.pfm");

        // Same geometry under both weathers, different light.
        let noon = dir.path().join("Town01/ClearNoon/000000");
        let night = dir.path().join("Town01/ClearNight/000000");
        assert_eq!(
            std::fs::read(noon.join("depth_0.png")).unwrap(),
            std::fs::read(night.join("depth_0.png")).unwrap()
        );
        assert_ne!(
            std::fs::read(noon.join("rgb_0.png")).unwrap(),
            std::fs::read(night.join("rgb_0.png")).unwrap()
        );

        let path = dir.path().join("manifest.json");
        manifest.save(&path).unwrap();
        let report = mbs_dataset::validate::validate_manifest(&path, Default::default(), &());
        assert!(report.is_clean(), "{:?}", report.problems);
    }

    #[test]
    fn scene_seeds_differ_between_frames_and_towns() {
        let spec = spec();
        let a = spec.scene_seed(&Frame { town: 0, index: 0 });
        let b = spec.scene_seed(&Frame { town: 0, index: 1 });
        let c = spec.scene_seed(&Frame { town: 1, index: 0 });
        assert!(a != b && a != c && b != c);
    }
}
