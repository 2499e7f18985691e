//! SceneFlow (FlyingThings3D, Driving, Monkaa) as its downloads unpack:
//! `frames_finalpass/` or `frames_cleanpass/` with the views in `left/` and
//! `right/` folders at any depth (`TEST/A/0000/left/0006.png` in
//! FlyingThings3D, `35mm_focallength/scene_forwards/fast/left/0001.png` in
//! Driving, `a_rain_of_stones_x2/left/0000.png` in Monkaa), and the left
//! views' disparity at the same place under `disparity/` as PFM
//! (`disparity/TEST/A/0000/left/0006.pfm`), dense and positive. The full
//! downloads have no occlusion maps, so SceneFlow's pairs have no NOC
//! pixels: only ALL is scored.

use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};

use mbs_core::Side;

use crate::DatasetError;
use crate::ground_truth::GroundTruthFile;
use crate::kitti::png_stems;
use crate::stereo_pair::StereoPair;

/// The render passes, in the order a dataset folder is searched: the
/// final pass (motion blur, depth of field) is the one usually scored.
const PASSES: [&str; 2] = ["frames_finalpass", "frames_cleanpass"];
/// The ground-truth folder beside the passes.
const DISPARITY: &str = "disparity";

/// Every frame under `dir` as a right-side pair with its ground truth.
/// `dir` is a SceneFlow folder holding a pass (the final pass when it
/// holds both) or a folder inside a pass (e.g. `frames_finalpass/TEST` for
/// FlyingThings3D's test split). A pair is named after its path inside the
/// pass without `left` (`TEST/A/0000/0006`), so that no two frames share a
/// name and outputs mirror the dataset's folders, and they come in that
/// order; two frames whose names would still meet (file names that are not
/// UTF-8) are an error naming both. Another folder, or one without frames,
/// is a layout error naming what was expected.
pub fn scene_flow_pairs(dir: &Path) -> Result<Vec<StereoPair>, DatasetError> {
    // Absolute, so that `.` inside a pass finds the pass above it.
    let dir = &std::path::absolute(dir).map_err(|source| DatasetError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let (pass, walk_from) = match PASSES.iter().map(|p| dir.join(p)).find(|p| p.is_dir()) {
        Some(pass) => (pass.clone(), pass),
        None => (pass_above(dir)?, dir.to_path_buf()),
    };
    let truth_root = pass.with_file_name(DISPARITY);
    let mut pairs: Vec<StereoPair> = Vec::new();
    let mut named: HashMap<String, PathBuf> = HashMap::new();
    for left in left_folders(&walk_from)? {
        let inside = left.strip_prefix(&pass).unwrap_or(&left).to_path_buf();
        let right = left.with_file_name("right");
        for frame in png_stems(&left)? {
            let truth = truth_root.join(&inside).join(format!("{frame}.pfm"));
            let mut id: Vec<String> = inside
                .parent()
                .into_iter()
                .flat_map(Path::components)
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            id.push(frame.clone());
            let id = id.join("/");
            let reference = left.join(format!("{frame}.png"));
            if let Some(first) = named.insert(id.clone(), reference.clone()) {
                return Err(DatasetError::Layout {
                    path: reference,
                    message: format!(
                        "is named {id}, as {} is: rename one of them",
                        first.display()
                    ),
                });
            }
            pairs.push(StereoPair {
                id,
                cameras: (0, 1),
                reference,
                target: right.join(format!("{frame}.png")),
                side: Side::Right,
                truth: truth.is_file().then_some(GroundTruthFile {
                    disparity: truth,
                    scale: 1.0,
                    noc: None,
                }),
                disparity_bound: None,
                calibration: None,
            });
        }
    }
    if pairs.is_empty() {
        return Err(DatasetError::Layout {
            path: dir.to_path_buf(),
            message: "no SceneFlow frames: expected left/ and right/ folders of .png views".into(),
        });
    }
    Ok(pairs)
}

/// The pass folder `dir` lies in, or a layout error saying what a
/// SceneFlow folder holds.
fn pass_above(dir: &Path) -> Result<PathBuf, DatasetError> {
    let mut above = PathBuf::new();
    for component in dir.components() {
        above.push(component);
        if matches!(component, Component::Normal(name) if PASSES.iter().any(|p| name == *p)) {
            return Ok(above);
        }
    }
    Err(DatasetError::Layout {
        path: dir.to_path_buf(),
        message: format!(
            "not a SceneFlow folder: expected {} or {} (with {DISPARITY}/ beside it), \
             or a folder inside one",
            PASSES[0], PASSES[1]
        ),
    })
}

/// The folders named `left` under `dir` (itself included), in path
/// order, following symbolic links (a link back to a folder above is not
/// walked twice). A `left` folder without a sibling `right` is an error
/// naming it: its frames would be left out without a word.
fn left_folders(dir: &Path) -> Result<Vec<PathBuf>, DatasetError> {
    let mut found = Vec::new();
    for entry in crate::walk::entries(dir) {
        let entry = entry?;
        let path = entry.path();
        if !entry.file_type().is_dir() || entry.file_name() != "left" {
            continue;
        }
        if !path.with_file_name("right").is_dir() {
            return Err(DatasetError::Layout {
                path: path.to_path_buf(),
                message: "has no sibling right/ folder: a SceneFlow frame needs both views".into(),
            });
        }
        found.push(path.to_path_buf());
    }
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_test_support::files::touch;

    /// A frame of `folder` (inside a pass), with its disparity when `truth`.
    fn frame(root: &Path, pass: &str, folder: &str, name: &str, truth: bool) {
        for side in ["left", "right"] {
            touch(&root.join(format!("{pass}/{folder}/{side}/{name}.png")));
        }
        if truth {
            touch(&root.join(format!("disparity/{folder}/left/{name}.pfm")));
        }
    }

    #[test]
    fn the_final_pass_is_read_at_every_depth_with_its_disparity() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        frame(root, "frames_finalpass", "TEST/A/0000", "0006", true);
        frame(root, "frames_finalpass", "TEST/A/0000", "0007", false);
        frame(
            root,
            "frames_finalpass",
            "a_rain_of_stones_x2",
            "0000",
            true,
        );
        frame(root, "frames_cleanpass", "TEST/A/0000", "0006", true);
        let pairs = scene_flow_pairs(root).unwrap();
        let ids: Vec<&str> = pairs.iter().map(|p| p.id.as_str()).collect();
        assert_eq!(
            ids,
            [
                "TEST/A/0000/0006",
                "TEST/A/0000/0007",
                "a_rain_of_stones_x2/0000"
            ]
        );
        assert_eq!(
            pairs[0].target,
            root.join("frames_finalpass/TEST/A/0000/right/0006.png")
        );
        let truth = pairs[0].truth.as_ref().unwrap();
        assert_eq!(
            truth.disparity,
            root.join("disparity/TEST/A/0000/left/0006.pfm")
        );
        assert_eq!(truth.noc, None);
        assert!(pairs[1].truth.is_none());
    }

    /// `TEST/A/0000` and `TEST/A_0000` used to both name their frame 0006
    /// `TEST_A_0000_0006`: predict wrote one file for two frames.
    #[test]
    fn frames_whose_folders_differ_have_different_names() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        frame(root, "frames_finalpass", "TEST/A/0000", "0006", true);
        frame(root, "frames_finalpass", "TEST/A_0000", "0006", true);
        let pairs = scene_flow_pairs(root).unwrap();
        let ids: Vec<&str> = pairs.iter().map(|p| p.id.as_str()).collect();
        assert_eq!(ids, ["TEST/A/0000/0006", "TEST/A_0000/0006"]);
    }

    #[test]
    fn a_folder_inside_a_pass_gives_its_frames_only() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        frame(root, "frames_cleanpass", "TEST/B/0001", "0010", true);
        frame(root, "frames_cleanpass", "TRAIN/B/0001", "0010", true);
        let pairs = scene_flow_pairs(&root.join("frames_cleanpass/TEST")).unwrap();
        assert_eq!(pairs.len(), 1);
        assert_eq!(pairs[0].id, "TEST/B/0001/0010");
        assert!(pairs[0].truth.is_some());
    }

    #[test]
    fn other_folders_name_the_expected_layout() {
        let dir = tempfile::tempdir().unwrap();
        let err = scene_flow_pairs(dir.path()).unwrap_err().to_string();
        assert!(
            err.contains("not a SceneFlow folder") && err.contains("frames_finalpass"),
            "{err}"
        );
        std::fs::create_dir_all(dir.path().join("frames_cleanpass/TEST")).unwrap();
        let err = scene_flow_pairs(dir.path()).unwrap_err().to_string();
        assert!(err.contains("no SceneFlow frames"), "{err}");
    }

    /// A scene folder that is a symbolic link (data kept on another disk)
    /// used to be skipped without a word; its frames are now listed under
    /// the link's name, and a link back to a folder above lists nothing
    /// twice.
    #[cfg(unix)]
    #[test]
    fn linked_folders_are_followed_and_loops_walked_once() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("flyingthings3d");
        frame(&root, "frames_finalpass", "TEST/A/0000", "0006", true);
        let elsewhere = dir.path().join("other-disk");
        frame(&elsewhere, "frames_finalpass", "TEST/A/0001", "0007", false);
        std::os::unix::fs::symlink(
            elsewhere.join("frames_finalpass/TEST/A/0001"),
            root.join("frames_finalpass/TEST/A/0001"),
        )
        .unwrap();
        touch(&root.join("disparity/TEST/A/0001/left/0007.pfm"));
        std::os::unix::fs::symlink("../..", root.join("frames_finalpass/TEST/A/up")).unwrap();
        let pairs = scene_flow_pairs(&root).unwrap();
        let ids: Vec<&str> = pairs.iter().map(|p| p.id.as_str()).collect();
        assert_eq!(ids, ["TEST/A/0000/0006", "TEST/A/0001/0007"]);
        assert_eq!(
            pairs[1].truth.as_ref().unwrap().disparity,
            root.join("disparity/TEST/A/0001/left/0007.pfm")
        );
    }

    /// A `left/` folder without its `right/` sibling used to be skipped
    /// without a word; now it is named.
    #[test]
    fn a_left_folder_without_right_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        frame(root, "frames_finalpass", "TEST/A/0000", "0006", true);
        frame(root, "frames_finalpass", "TEST/A/0001", "0006", true);
        let right = root.join("frames_finalpass/TEST/A/0001/right");
        std::fs::remove_dir_all(&right).unwrap();
        let err = scene_flow_pairs(root).unwrap_err().to_string();
        let left = root.join("frames_finalpass/TEST/A/0001/left");
        assert!(
            err.contains(&left.display().to_string()) && err.contains("no sibling right/"),
            "{err}"
        );
    }
}
