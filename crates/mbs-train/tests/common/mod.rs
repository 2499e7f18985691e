//! Shared by the end-to-end tests: small synthetic MBS20K-style datasets.
#![allow(dead_code)] // each test binary uses a different subset

use std::path::{Path, PathBuf};

use mbs_core::Rig;
use mbs_synth::dataset::DatasetSpec;
use mbs_synth::{SceneConfig, Weather};

/// Renders `frames` scenes per town (two training towns, Town10 held out)
/// under two weathers at `width` x `height` (90 degree field of view, the
/// MBS20K rig of 5 cameras 0.5 m apart) and returns the manifest's path.
pub fn synthesise(root: &Path, frames: usize, width: u32, height: u32) -> PathBuf {
    write(
        root,
        DatasetSpec {
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
        },
    )
}

/// The set `mbs-tool synth --out DIR --seed SEED --frames 6 --towns
/// Town01,Town10 --weathers ClearNoon --width 192 --height 96 --focal 96
/// --no-checksums` writes (Town10 held out); returns the manifest's path.
pub fn synthesise_like_the_cli(root: &Path, seed: u64) -> PathBuf {
    let rig = Rig::centred(5, 0.5, 96.0, 192, 96);
    write(
        root,
        DatasetSpec {
            rig,
            towns: vec!["Town01".into(), "Town10".into()],
            weathers: vec![Weather::ClearNoon],
            frames: 6,
            seed,
            test_towns: vec!["Town10".into()],
            scene: SceneConfig::centred_on(&rig),
            supersample: 2,
            max_depth_m: 200.0,
            checksums: false,
        },
    )
}

/// Writes every frame of `spec` under `root` and its manifest.
fn write(root: &Path, spec: DatasetSpec) -> PathBuf {
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
