//! Shared by the end-to-end tests: a small synthetic MBS20K-style dataset.

use std::path::{Path, PathBuf};

use mbs_core::Rig;
use mbs_synth::dataset::DatasetSpec;
use mbs_synth::{SceneConfig, Weather};

/// Renders `frames` scenes per town (two training towns, Town10 held out)
/// under two weathers at `width` x `height` (90 degree field of view, the
/// MBS20K rig of 5 cameras 0.5 m apart) and returns the manifest's path.
pub fn synthesise(root: &Path, frames: usize, width: u32, height: u32) -> PathBuf {
    let spec = DatasetSpec {
        rig: Rig::centred(5, 0.5, f64::from(width) / 2.0, width, height),
        towns: vec!["Town01".into(), "Town02".into(), "Town10".into()],
        weathers: vec![Weather::ClearNoon, Weather::ClearSunset],
        frames,
        seed: 11,
        test_towns: vec!["Town10".into()],
        scene: SceneConfig::default(),
        supersample: 2,
        max_depth_m: 200.0,
        checksums: false,
    };
    for frame in spec.frames() {
        spec.write_frame(root, &frame)
            .expect("synthetic frame is written");
    }
    let path = root.join("manifest.json");
    spec.manifest(root)
        .expect("manifest of the synthetic set")
        .save(&path)
        .expect("manifest is written");
    path
}
