//! The two-view benchmarks that share Middlebury's file layout, read from
//! their folders exactly as the downloads unpack:
//!
//! - Middlebury 2014 / MiddEval3: `trainingF|H|Q/<Scene>/im0.png, im1.png`
//!   with `disp0GT.pfm` and `mask0nocc.png` beside them (the test folders
//!   have no ground truth);
//! - ETH3D two-view: `two_view_training/<scene>/im0.png, im1.png`, the
//!   ground truth in the sibling `two_view_training_gt/<scene>/` (same two
//!   files).
//!
//! Both encode ground truth alike: `inf` in the PFM is an invalid pixel,
//! and in `mask0nocc.png` 255 is a non-occluded pixel, 128 an occluded one
//! and 0 one without ground truth. Both put a `calib.txt` in each scene
//! folder whose `ndisp` bounds the scene's disparities (at that folder's
//! resolution); it becomes the pair's [`StereoPair::disparity_bound`].

use std::path::{Path, PathBuf};

use mbs_core::Side;

use crate::DatasetError;
use crate::ground_truth::{GroundTruthFile, NocSource};
use crate::stereo_pair::StereoPair;

/// The views of a scene.
const VIEWS: [&str; 2] = ["im0.png", "im1.png"];
/// The ground-truth disparity of the left view.
const DISPARITY: &str = "disp0GT.pfm";
/// The left view's occlusion mask.
const MASK: &str = "mask0nocc.png";
/// The scene's calibration, with its disparity bound.
const CALIBRATION: &str = "calib.txt";

/// The `ndisp` of the scene folder `scene`'s `calib.txt` (lines of
/// `key=value`): `None` without the file or the key; a value that is not
/// a positive whole number, a second `ndisp` line, or a `calib.txt` that
/// is not a regular file (a FIFO would block the read) is an error naming
/// the file.
fn disparity_bound(scene: &Path) -> Result<Option<u32>, DatasetError> {
    let path = scene.join(CALIBRATION);
    let Some(text) = mbs_core::regular::read_text_if_present(&path)? else {
        return Ok(None);
    };
    let values: Vec<&str> = text
        .lines()
        .filter_map(|line| line.split_once('='))
        .filter(|(key, _)| key.trim() == "ndisp")
        .map(|(_, value)| value.trim())
        .collect();
    let value = match values.as_slice() {
        [] => return Ok(None),
        [value] => *value,
        _ => {
            return Err(DatasetError::Layout {
                path,
                message: format!(
                    "has {} ndisp lines ({}); expected one",
                    values.len(),
                    values.join(", ")
                ),
            });
        }
    };
    match value.parse::<u32>() {
        Ok(n) if n > 0 => Ok(Some(n)),
        _ => Err(DatasetError::Layout {
            path,
            message: format!("ndisp={value} is not a positive whole number of disparities"),
        }),
    }
}

/// The two benchmarks of this layout.
#[derive(Debug, Clone, Copy)]
enum TwoView {
    /// Middlebury 2014 / MiddEval3: the ground truth beside the views.
    Middlebury,
    /// ETH3D two-view: the ground truth in a sibling `_gt` folder.
    Eth3d,
}

impl TwoView {
    /// The benchmark's name, as messages spell it.
    fn name(self) -> &'static str {
        match self {
            TwoView::Middlebury => "Middlebury",
            TwoView::Eth3d => "ETH3D",
        }
    }
}

/// Every scene of a Middlebury 2014 / MiddEval3 folder as a pair (see
/// [`two_view_pairs`]).
pub fn middlebury_pairs(root: &Path) -> Result<Vec<StereoPair>, DatasetError> {
    two_view_pairs(root, TwoView::Middlebury)
}

/// Every scene of an ETH3D two-view folder as a pair, its ground truth
/// from the sibling `<folder>_gt` (see [`two_view_pairs`]).
pub fn eth3d_pairs(root: &Path) -> Result<Vec<StereoPair>, DatasetError> {
    two_view_pairs(root, TwoView::Eth3d)
}

/// Where the ground truth of `scene` under `root` lies: the scene's own
/// folder (Middlebury) or the sibling `<root>_gt` folder (ETH3D; `root`
/// made absolute first, so that `.` or `..` name their folder).
fn truth_dir(benchmark: TwoView, root: &Path, scene: &str) -> PathBuf {
    match benchmark {
        TwoView::Eth3d => {
            let root = std::path::absolute(root).unwrap_or_else(|_| root.to_path_buf());
            let root = match root.file_name() {
                Some(_) => root,
                None => root.canonicalize().unwrap_or(root),
            };
            let mut name = root.file_name().unwrap_or_default().to_os_string();
            name.push("_gt");
            root.with_file_name(name).join(scene)
        }
        TwoView::Middlebury => root.join(scene),
    }
}

/// Every scene of `root` (a folder of scene folders, each with `im0.png`
/// and `im1.png`) as a right-side pair named after its folder, in name
/// order, with its ground truth where the benchmark has it and its
/// `calib.txt`'s disparity bound. A folder with no scene is a layout
/// error naming what was expected. When any scene's ground truth has its
/// `mask0nocc.png`, every scene's must: one without is read as missing
/// when it is scored (an error naming it), so that NOC and OCC are never
/// pooled over fewer scenes than ALL.
fn two_view_pairs(root: &Path, benchmark: TwoView) -> Result<Vec<StereoPair>, DatasetError> {
    let scenes = scene_names(root, benchmark)?;
    let masks = scenes.iter().any(|scene| {
        let truth = truth_dir(benchmark, root, scene);
        present(&truth.join(DISPARITY)) && present(&truth.join(MASK))
    });
    scenes
        .into_iter()
        .map(|scene| {
            let truth = truth_dir(benchmark, root, &scene);
            let disparity = truth.join(DISPARITY);
            let mask = truth.join(MASK);
            let calibration = root.join(&scene).join(CALIBRATION);
            Ok(StereoPair {
                disparity_bound: disparity_bound(&root.join(&scene))?,
                calibration: calibration.exists().then_some(calibration),
                cameras: (0, 1),
                reference: root.join(&scene).join(VIEWS[0]),
                target: root.join(&scene).join(VIEWS[1]),
                side: Side::Right,
                truth: disparity.is_file().then(|| GroundTruthFile {
                    disparity,
                    scale: 1.0,
                    noc: masks.then_some(NocSource::Levels(mask)),
                }),
                id: scene,
            })
        })
        .collect()
}

/// Whether anything is at `path` (a file, a folder, a FIFO, a link even
/// to nothing).
fn present(path: &Path) -> bool {
    path.symlink_metadata().is_ok()
}

/// The scenes of `root`, sorted: its folders holding `im0.png` or
/// `im1.png`. A folder holding one view and not the other, a folder that
/// cannot be read or a scene name that is not UTF-8 is an error naming
/// it (a scene left out would be missing from scores and submissions
/// without a word); a view that is not a file is named when it is read.
fn scene_names(root: &Path, benchmark: TwoView) -> Result<Vec<String>, DatasetError> {
    let entries = std::fs::read_dir(root).map_err(|e| DatasetError::Layout {
        path: root.to_path_buf(),
        message: format!(
            "cannot be read ({e}); expected a {} folder of scenes",
            benchmark.name()
        ),
    })?;
    let mut scenes = Vec::new();
    for entry in entries {
        let dir = entry
            .map_err(|source| DatasetError::Io {
                path: root.to_path_buf(),
                source,
            })?
            .path();
        match VIEWS.map(|view| present(&dir.join(view))) {
            [false, false] => continue,
            [true, true] => scenes.push(crate::utf8_file_name(&dir)?.to_string()),
            [has_first, _] => {
                let (there, missing) = if has_first { (0, 1) } else { (1, 0) };
                return Err(DatasetError::Layout {
                    path: dir.join(VIEWS[missing]),
                    message: format!(
                        "no such file: scene {} has {} but not {}; a {} scene needs both \
                         views",
                        crate::utf8_file_name(&dir)?,
                        VIEWS[there],
                        VIEWS[missing],
                        benchmark.name()
                    ),
                });
            }
        }
    }
    scenes.sort();
    if scenes.is_empty() {
        return Err(DatasetError::Layout {
            path: root.to_path_buf(),
            message: format!(
                "no {} scene: expected folders holding {} and {}",
                benchmark.name(),
                VIEWS[0],
                VIEWS[1]
            ),
        });
    }
    Ok(scenes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_core::formats::pfm::{Endian, write_pfm_grey};
    use mbs_core::formats::rgb::write_mask_png;
    use mbs_core::{FloatImage, MaskImage};
    use mbs_test_support::files::touch;

    /// A scene folder with its views, and ground truth in `truth` when given.
    fn scene(dir: &Path, truth: Option<&Path>) {
        for view in VIEWS {
            touch(&dir.join(view));
        }
        if let Some(truth) = truth {
            std::fs::create_dir_all(truth).unwrap();
            let map = FloatImage::from_raw(3, 1, vec![2.5, f32::INFINITY, 4.0]).unwrap();
            write_pfm_grey(&truth.join(DISPARITY), &map, Endian::Little).unwrap();
            let mask = MaskImage::from_raw(3, 1, vec![255, 0, 128]).unwrap();
            write_mask_png(&truth.join(MASK), &mask).unwrap();
        }
    }

    #[test]
    fn middlebury_scenes_are_pairs_with_their_ground_truth_beside_them() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("MiddEval3/trainingQ");
        scene(&root.join("Motorcycle"), Some(&root.join("Motorcycle")));
        scene(&root.join("Adirondack"), Some(&root.join("Adirondack")));
        std::fs::create_dir_all(root.join("not-a-scene")).unwrap();
        let pairs = middlebury_pairs(&root).unwrap();
        let ids: Vec<&str> = pairs.iter().map(|p| p.id.as_str()).collect();
        assert_eq!(ids, ["Adirondack", "Motorcycle"]);
        let pair = &pairs[0];
        assert_eq!(pair.reference, root.join("Adirondack/im0.png"));
        assert_eq!(pair.target, root.join("Adirondack/im1.png"));
        assert_eq!(pair.side, Side::Right);
        let truth = pair.truth.as_ref().unwrap().load(None).unwrap();
        assert_eq!(truth.disparity.as_raw(), &[2.5, f32::INFINITY, 4.0]);
        // 255 is visible, 128 occluded: only the first pixel is non-occluded.
        assert_eq!(truth.noc.unwrap().as_raw(), &[255, 0, 0]);
    }

    #[test]
    fn eth3d_ground_truth_comes_from_the_sibling_gt_folder() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("two_view_training");
        let gt = dir.path().join("two_view_training_gt");
        scene(
            &root.join("delivery_area_1l"),
            Some(&gt.join("delivery_area_1l")),
        );
        scene(&root.join("forest_1s"), None);
        let pairs = eth3d_pairs(&root).unwrap();
        assert_eq!(pairs.len(), 2);
        let truth = pairs[0].truth.as_ref().unwrap();
        assert_eq!(truth.disparity, gt.join("delivery_area_1l").join(DISPARITY));
        assert_eq!(
            truth.noc,
            Some(NocSource::Levels(gt.join("delivery_area_1l").join(MASK)))
        );
        assert_eq!(pairs[1].id, "forest_1s");
        assert!(pairs[1].truth.is_none());
    }

    #[test]
    fn calib_ndisp_bounds_the_scene_and_a_bad_one_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("trainingH");
        for name in ["Adirondack", "Jadeplant", "Piano"] {
            scene(&root.join(name), None);
        }
        let calib = "cam0=[1 0 0; 0 1 0; 0 0 1]\ndoffs=0\nwidth=1436\nheight=992\n";
        std::fs::write(
            root.join("Adirondack").join(CALIBRATION),
            format!("{calib}ndisp=145\nvmin=12\n"),
        )
        .unwrap();
        std::fs::write(root.join("Jadeplant").join(CALIBRATION), calib).unwrap();
        let pairs = middlebury_pairs(&root).unwrap();
        let bounds: Vec<Option<u32>> = pairs.iter().map(|p| p.disparity_bound).collect();
        // Piano has no calib.txt, Jadeplant's has no ndisp.
        assert_eq!(bounds, [Some(145), None, None]);

        let bad = root.join("Piano").join(CALIBRATION);
        std::fs::write(&bad, "ndisp=-3\n").unwrap();
        let err = middlebury_pairs(&root).unwrap_err().to_string();
        assert!(
            err.contains(&bad.display().to_string()) && err.contains("ndisp=-3"),
            "{err}"
        );
        // Two ndisp lines used to take the first without a word.
        std::fs::write(&bad, "ndisp=64\nndisp=128\n").unwrap();
        let err = middlebury_pairs(&root).unwrap_err().to_string();
        assert!(err.contains("2 ndisp lines (64, 128)"), "{err}");
    }

    /// `--eth3d .` from inside the folder finds the `_gt` sibling as the
    /// absolute path does.
    #[test]
    fn eth3d_ground_truth_is_found_from_a_relative_dot() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("two_view_training");
        scene(&root.join("delivery_area_1l"), None);
        let gt = dir.path().join("two_view_training_gt/delivery_area_1l");
        std::fs::create_dir_all(&gt).unwrap();
        std::fs::write(gt.join(DISPARITY), b"Pf").unwrap();
        let dotted = root.join(".");
        let pairs = eth3d_pairs(&dotted).unwrap();
        assert_eq!(
            pairs[0].truth.as_ref().map(|t| t.disparity.clone()),
            Some(std::path::absolute(&gt).unwrap().join(DISPARITY))
        );
    }

    #[test]
    fn a_folder_without_scenes_names_what_was_expected() {
        let dir = tempfile::tempdir().unwrap();
        let err = middlebury_pairs(dir.path()).unwrap_err().to_string();
        assert!(
            err.contains("no Middlebury scene") && err.contains("im0.png"),
            "{err}"
        );
        let missing = dir.path().join("nowhere");
        let err = eth3d_pairs(&missing).unwrap_err().to_string();
        assert!(
            err.contains("nowhere") && err.contains("expected a ETH3D folder"),
            "{err}"
        );
    }

    /// A scene folder with one view and not the other used to be left
    /// out without a word (a MiddEval3 submission then lacked the scene
    /// and `submit` exited 0); now the listing names the scene and the
    /// missing view, in both layouts.
    #[test]
    fn a_scene_with_one_view_is_named_not_left_out() {
        let dir = tempfile::tempdir().unwrap();
        for (root, list) in [
            (
                dir.path().join("testH"),
                middlebury_pairs as fn(&Path) -> Result<Vec<StereoPair>, DatasetError>,
            ),
            (dir.path().join("two_view_test"), eth3d_pairs),
        ] {
            scene(&root.join("Australia"), None);
            scene(&root.join("Bicycle2"), None);
            assert_eq!(list(&root).unwrap().len(), 2);
            std::fs::remove_file(root.join("Bicycle2").join(VIEWS[1])).unwrap();
            let err = list(&root).unwrap_err().to_string();
            let missing = root.join("Bicycle2").join(VIEWS[1]);
            assert!(
                err.contains(&missing.display().to_string())
                    && err.contains("scene Bicycle2 has im0.png but not im1.png"),
                "{err}"
            );
            touch(&root.join("Bicycle2").join(VIEWS[1]));
            std::fs::remove_file(root.join("Australia").join(VIEWS[0])).unwrap();
            let err = list(&root).unwrap_err().to_string();
            assert!(
                err.contains("scene Australia has im1.png but not im0.png"),
                "{err}"
            );
        }
    }

    /// When a scene's ground truth has its mask0nocc.png, every scene's
    /// has one to read: a missing one used to leave its scene out of NOC
    /// and OCC only (their figures then over fewer scenes than ALL's);
    /// now reading it is an error naming the mask. A folder without any
    /// mask has no NOC at all.
    #[test]
    fn a_missing_noc_mask_is_an_error_when_the_other_scenes_have_theirs() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("trainingQ");
        for name in ["Adirondack", "Piano"] {
            scene(&root.join(name), Some(&root.join(name)));
        }
        let mask = root.join("Piano").join(MASK);
        std::fs::remove_file(&mask).unwrap();
        let pairs = middlebury_pairs(&root).unwrap();
        assert!(pairs[0].truth.as_ref().unwrap().load(None).is_ok());
        let truth = pairs[1].truth.as_ref().unwrap();
        assert_eq!(truth.noc, Some(NocSource::Levels(mask.clone())));
        let err = truth.load(None).unwrap_err().to_string();
        assert!(
            err.starts_with(&format!("{}: no such file", mask.display()))
                && err.contains(DISPARITY),
            "{err}"
        );
        // A mask that does not decode is an error naming it too.
        std::fs::write(&mask, b"not a PNG").unwrap();
        let err = truth.load(None).unwrap_err().to_string();
        assert!(err.starts_with(&mask.display().to_string()), "{err}");
        std::fs::remove_file(&mask).unwrap();
        std::fs::remove_file(root.join("Adirondack").join(MASK)).unwrap();
        let pairs = middlebury_pairs(&root).unwrap();
        assert!(
            pairs
                .iter()
                .all(|p| p.truth.as_ref().unwrap().noc.is_none())
        );
    }
}
