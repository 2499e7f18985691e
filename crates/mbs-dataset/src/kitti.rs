//! KITTI stereo folders (conventions §3): 2015 (`image_2`, `image_3`, `disp_occ_0`,
//! `disp_noc_0`) and 2012 (`colored_0`, `colored_1`, `disp_occ`,
//! `disp_noc`), training or testing.

use std::path::{Path, PathBuf};

use mbs_core::Side;

use crate::error::DatasetError;
use crate::ground_truth::{GroundTruthFile, NocSource};
use crate::stereo_pair::StereoPair;

/// Which KITTI benchmark a folder belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KittiVersion {
    /// KITTI 2015: `image_2` / `image_3`.
    Kitti2015,
    /// KITTI 2012: `colored_0` / `colored_1`.
    Kitti2012,
}

/// A KITTI split folder and its frames.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiFolder {
    /// The split folder, e.g. `kitti2015/training`.
    pub root: PathBuf,
    /// The benchmark version, from the folder names.
    pub version: KittiVersion,
    /// File stems of the left views (e.g. `000000_10`), sorted.
    pub frames: Vec<String>,
}

impl KittiFolder {
    /// Detects the layout of `root` and lists the PNG frames of its left
    /// view folder.
    pub fn open(root: &Path) -> Result<KittiFolder, DatasetError> {
        let version = [KittiVersion::Kitti2015, KittiVersion::Kitti2012]
            .into_iter()
            .find(|v| {
                let (l, r) = v.view_dirs();
                root.join(l).is_dir() && root.join(r).is_dir()
            })
            .ok_or_else(|| DatasetError::Layout {
                path: root.to_path_buf(),
                message:
                    "not a KITTI folder (expected image_2 and image_3, or colored_0 and colored_1)"
                        .into(),
            })?;
        let left_dir = root.join(version.view_dirs().0);
        let frames = png_stems(&left_dir)?;
        if frames.is_empty() {
            return Err(DatasetError::Layout {
                path: left_dir,
                message: "no .png views".into(),
            });
        }
        Ok(KittiFolder {
            root: root.to_path_buf(),
            version,
            frames,
        })
    }

    /// The left view of a frame.
    pub fn left(&self, frame: &str) -> PathBuf {
        self.root
            .join(self.version.view_dirs().0)
            .join(format!("{frame}.png"))
    }

    /// The right view of a frame.
    pub fn right(&self, frame: &str) -> PathBuf {
        self.root
            .join(self.version.view_dirs().1)
            .join(format!("{frame}.png"))
    }

    /// The ground-truth disparity of the left view (all valid pixels), when
    /// the file exists (training `*_10` frames).
    pub fn disparity_occ(&self, frame: &str) -> Option<PathBuf> {
        Some(
            self.root
                .join(self.version.gt_dirs().0)
                .join(format!("{frame}.png")),
        )
        .filter(|p| p.is_file())
    }

    /// The non-occluded ground-truth disparity of the left view, when it exists.
    pub fn disparity_noc(&self, frame: &str) -> Option<PathBuf> {
        Some(
            self.root
                .join(self.version.gt_dirs().1)
                .join(format!("{frame}.png")),
        )
        .filter(|p| p.is_file())
    }
}

/// The stems of the `.png` files in `dir`, sorted.
pub fn png_stems(dir: &Path) -> Result<Vec<String>, DatasetError> {
    let io = |source| DatasetError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut stems = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        let name = crate::utf8_file_name(&path)?;
        if let Some(stem) = name.strip_suffix(".png") {
            stems.push(stem.to_string());
        }
    }
    stems.sort();
    Ok(stems)
}

impl KittiVersion {
    /// The left and right view folder names.
    pub fn view_dirs(self) -> (&'static str, &'static str) {
        match self {
            KittiVersion::Kitti2015 => ("image_2", "image_3"),
            KittiVersion::Kitti2012 => ("colored_0", "colored_1"),
        }
    }

    /// Whether `dir` is named like a KITTI ground-truth folder of either
    /// version (`disp_occ_0`, `disp_noc_0`, `disp_occ`, `disp_noc`).
    pub fn is_ground_truth_dir(dir: &Path) -> bool {
        let name = dir.file_name().and_then(|n| n.to_str()).unwrap_or("");
        [KittiVersion::Kitti2015, KittiVersion::Kitti2012]
            .iter()
            .any(|v| name == v.gt_dirs().0 || name == v.gt_dirs().1)
    }

    /// The version whose all-pixels ground-truth folder (`disp_occ_0` or
    /// `disp_occ`) is in `dir`, if either is.
    pub fn of_ground_truth(dir: &Path) -> Option<KittiVersion> {
        [KittiVersion::Kitti2015, KittiVersion::Kitti2012]
            .into_iter()
            .find(|v| dir.join(v.gt_dirs().0).is_dir())
    }

    /// The benchmark's name with its year (`KITTI 2015`).
    pub fn name(self) -> &'static str {
        match self {
            KittiVersion::Kitti2015 => "KITTI 2015",
            KittiVersion::Kitti2012 => "KITTI 2012",
        }
    }

    /// The all-pixels and non-occluded ground-truth folder names.
    pub fn gt_dirs(self) -> (&'static str, &'static str) {
        match self {
            KittiVersion::Kitti2015 => ("disp_occ_0", "disp_noc_0"),
            KittiVersion::Kitti2012 => ("disp_occ", "disp_noc"),
        }
    }
}

/// Which frames of a KITTI folder are pairs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KittiFrames {
    /// Every frame of the left view folder.
    All,
    /// The `*_10` frames: those the benchmark's ground truth covers.
    Benchmark,
}

/// The benchmark's frames of the KITTI folder `dir` (its `*_10` frames,
/// those the ground truth covers) as pairs.
pub fn benchmark_pairs(dir: &Path) -> Result<Vec<StereoPair>, DatasetError> {
    view_pairs(&KittiFolder::open(dir)?, KittiFrames::Benchmark)
}

/// The ground truth of a KITTI frame, from the folder names of `version`
/// under `dir`, when the all-pixels map exists. Its non-occluded map is
/// the frame's file in the non-occluded folder whenever that folder is
/// there: a frame without its file is read as missing when it is scored
/// (an error naming it), so that NOC and OCC are never pooled over fewer
/// frames than ALL.
fn frame_truth(dir: &Path, version: KittiVersion, frame: &str) -> Option<GroundTruthFile> {
    let (occ, noc) = version.gt_dirs();
    let file = format!("{frame}.png");
    let disparity = dir.join(occ).join(&file);
    let noc = dir.join(noc);
    disparity.is_file().then(|| GroundTruthFile {
        disparity,
        scale: 1.0,
        noc: noc
            .symlink_metadata()
            .is_ok()
            .then(|| NocSource::Map(noc.join(&file))),
    })
}

/// The frames of a KITTI folder's view folders as pairs.
pub fn view_pairs(
    folder: &KittiFolder,
    frames: KittiFrames,
) -> Result<Vec<StereoPair>, DatasetError> {
    let pairs: Vec<StereoPair> = folder
        .frames
        .iter()
        .filter(|f| frames == KittiFrames::All || f.ends_with("_10"))
        .map(|f| StereoPair {
            id: f.clone(),
            cameras: (0, 1),
            reference: folder.left(f),
            target: folder.right(f),
            side: Side::Right,
            truth: frame_truth(&folder.root, folder.version, f),
            disparity_bound: None,
            calibration: None,
        })
        .collect();
    if pairs.is_empty() {
        return Err(DatasetError::Layout {
            path: folder.root.join(folder.version.view_dirs().0),
            message: "no *_10.png frames".into(),
        });
    }
    Ok(pairs)
}

/// The frames of a KITTI 2015 (`disp_occ_0`, `disp_noc_0`) or 2012
/// (`disp_occ`, `disp_noc`) training folder that have ground truth, sorted
/// by name. The views' paths are where KITTI keeps them; they are not
/// checked.
pub fn truth_pairs(dir: &Path) -> Result<Vec<StereoPair>, DatasetError> {
    let version = KittiVersion::of_ground_truth(dir).ok_or_else(|| DatasetError::Layout {
        path: dir.to_path_buf(),
        message: "no KITTI ground truth (expected disp_occ_0 or disp_occ)".into(),
    })?;
    let occ = dir.join(version.gt_dirs().0);
    let names = png_stems(&occ)?;
    if names.is_empty() {
        return Err(DatasetError::Layout {
            path: occ,
            message: "no ground-truth PNGs".into(),
        });
    }
    let (left, right) = version.view_dirs();
    Ok(names
        .into_iter()
        .map(|stem| {
            let file = format!("{stem}.png");
            StereoPair {
                cameras: (0, 1),
                reference: dir.join(left).join(&file),
                target: dir.join(right).join(&file),
                side: Side::Right,
                truth: frame_truth(dir, version, &stem),
                disparity_bound: None,
                calibration: None,
                id: stem,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_test_support::files::touch;

    #[test]
    fn detects_both_versions_and_lists_frames() {
        let dir = tempfile::tempdir().unwrap();
        let k15 = dir.path().join("k15");
        touch(&k15.join("image_2/000001_10.png"));
        touch(&k15.join("image_2/000000_11.png"));
        touch(&k15.join("image_3/000001_10.png"));
        touch(&k15.join("disp_occ_0/000001_10.png"));
        let folder = KittiFolder::open(&k15).unwrap();
        assert_eq!(folder.version, KittiVersion::Kitti2015);
        assert_eq!(folder.frames, ["000000_11", "000001_10"]);
        assert_eq!(folder.right("000001_10"), k15.join("image_3/000001_10.png"));
        assert!(folder.disparity_occ("000001_10").is_some());
        assert!(folder.disparity_noc("000001_10").is_none());

        let k12 = dir.path().join("k12");
        touch(&k12.join("colored_0/000003_10.png"));
        std::fs::create_dir_all(k12.join("colored_1")).unwrap();
        let folder = KittiFolder::open(&k12).unwrap();
        assert_eq!(folder.version, KittiVersion::Kitti2012);
        assert_eq!(
            folder.left("000003_10"),
            k12.join("colored_0/000003_10.png")
        );
    }

    #[test]
    fn other_folders_are_refused_with_their_path() {
        let dir = tempfile::tempdir().unwrap();
        let err = KittiFolder::open(dir.path()).unwrap_err().to_string();
        assert!(err.contains("not a KITTI folder"), "{err}");
        std::fs::create_dir_all(dir.path().join("image_2")).unwrap();
        std::fs::create_dir_all(dir.path().join("image_3")).unwrap();
        let err = KittiFolder::open(dir.path()).unwrap_err().to_string();
        assert!(err.contains("no .png views"), "{err}");
    }

    /// With a `disp_noc_0` folder, every frame's non-occluded map is read
    /// from it: one missing used to leave its frame out of NOC and OCC
    /// only (NOC 8.26 % where the full set gives 5.91 %); now reading it is
    /// an error naming the file. Without the folder no frame has NOC.
    #[test]
    fn a_missing_noc_map_is_an_error_when_the_folder_is_there() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("training");
        let map = mbs_core::FloatImage::from_pixel(4, 2, image::Luma([3.5]));
        for frame in ["000000_10", "000001_10"] {
            let file = format!("{frame}.png");
            for folder in ["image_2", "image_3"] {
                touch(&root.join(folder).join(&file));
            }
            let occ = root.join("disp_occ_0").join(&file);
            std::fs::create_dir_all(occ.parent().unwrap()).unwrap();
            mbs_core::formats::png16::write_kitti_disparity(&occ, &map).unwrap();
        }
        let noc = root.join("disp_noc_0/000000_10.png");
        std::fs::create_dir_all(noc.parent().unwrap()).unwrap();
        mbs_core::formats::png16::write_kitti_disparity(&noc, &map).unwrap();
        for pairs in [truth_pairs(&root).unwrap(), benchmark_pairs(&root).unwrap()] {
            let loaded = pairs[0].truth.as_ref().unwrap().load(None).unwrap();
            assert_eq!(loaded.noc.unwrap().as_raw(), &vec![255; 8]);
            let missing = root.join("disp_noc_0/000001_10.png");
            let err = pairs[1].truth.as_ref().unwrap().load(None).unwrap_err();
            let err = err.to_string();
            assert!(
                err.starts_with(&format!("{}: no such file", missing.display()))
                    && err.contains("disp_occ_0/000001_10.png"),
                "{err}"
            );
        }
        std::fs::remove_dir_all(root.join("disp_noc_0")).unwrap();
        let pairs = truth_pairs(&root).unwrap();
        assert!(
            pairs
                .iter()
                .all(|p| p.truth.as_ref().unwrap().noc.is_none())
        );
    }
}
