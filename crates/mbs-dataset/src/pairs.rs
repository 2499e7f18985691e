//! Stereo pairs wherever they come from: one pair of files, a benchmark's
//! folder (KITTI, Middlebury, ETH3D, DrivingStereo, SceneFlow) or one
//! camera pair of a manifest's samples, each with its ground truth when
//! the dataset has it. `predict`, `eval`, `extrapolate` and the
//! trainer's validation all list their pairs here.

use std::path::{Path, PathBuf};

use mbs_core::Side;
use mbs_core::inputs::InputFiles;

use crate::DatasetError;
use crate::benchmark::Benchmark;
use crate::driving_stereo::driving_stereo_pairs;
use crate::ground_truth::{GroundTruthFile, NocSource};
use crate::kitti::{KittiFolder, KittiVersion, png_stems};
use crate::manifest::{Manifest, Sample, Split, resolve};
use crate::scene_flow::scene_flow_pairs;
use crate::two_view::two_view_pairs;

/// One rectified pair: the views, the side of the target and the
/// reference view's ground truth, if any.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoPair {
    /// The sample id (manifests), frame name (KITTI, e.g. `000000_10`) or
    /// the left view's file stem (one pair): outputs are named after it.
    pub id: String,
    /// Camera indices of the reference and target (KITTI and one pair: 0 and 1).
    pub cameras: (usize, usize),
    /// The reference view (the disparity lives on its grid).
    pub reference: PathBuf,
    /// The target view.
    pub target: PathBuf,
    /// Which side of the reference the target lies on.
    pub side: Side,
    /// The reference view's ground truth, when the dataset has it.
    pub truth: Option<GroundTruthFile>,
    /// The dataset's bound on the pair's disparities, when it states one:
    /// they lie in `0..n` (Middlebury's and ETH3D's `calib.txt` `ndisp`).
    pub disparity_bound: Option<u32>,
}

impl StereoPair {
    /// Every file the pair is read from: the views, the ground truth and
    /// its mask, and the `calib.txt` beside the views that bounds the
    /// disparities.
    pub fn input_files(&self) -> Vec<PathBuf> {
        let mut files = vec![self.reference.clone(), self.target.clone()];
        if let Some(truth) = &self.truth {
            files.push(truth.disparity.clone());
            if let Some(noc) = &truth.noc {
                files.push(noc.path().to_path_buf());
            }
        }
        if self.disparity_bound.is_some() {
            files.push(self.reference.with_file_name(crate::two_view::CALIBRATION));
        }
        files
    }
}

/// Every input file of `pairs`, for refusing outputs that would replace one.
pub fn input_files<'a>(pairs: impl IntoIterator<Item = &'a StereoPair>) -> InputFiles {
    let mut inputs = InputFiles::new();
    inputs.extend(pairs.into_iter().flat_map(StereoPair::input_files));
    inputs
}

/// Which frames of a KITTI folder are pairs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KittiFrames {
    /// Every frame of the left view folder.
    All,
    /// The `*_10` frames: those the benchmark's ground truth covers.
    Benchmark,
}

/// Where a command's pairs come from.
#[derive(Debug, Clone, PartialEq)]
pub enum PairSource {
    /// One pair of files, the target right of the reference.
    Single {
        /// The left (reference) view.
        left: PathBuf,
        /// The right (target) view.
        right: PathBuf,
    },
    /// A KITTI 2015 or 2012 split folder (conventions §3).
    Kitti {
        /// The split folder, e.g. `kitti2015/training`.
        dir: PathBuf,
        /// Which of its frames are pairs.
        frames: KittiFrames,
    },
    /// A benchmark's folder in its own layout, its frames with ground
    /// truth those the benchmark scores (KITTI: the `*_10` frames).
    Benchmark {
        /// Which benchmark's layout.
        benchmark: Benchmark,
        /// The folder, e.g. `kitti2015/training`, `MiddEval3/trainingH`,
        /// `two_view_training`, a DrivingStereo weather folder or a
        /// SceneFlow folder.
        dir: PathBuf,
    },
    /// One camera pair of every sample of a manifest.
    Manifest {
        /// The manifest file, which relative paths are resolved against.
        path: PathBuf,
        /// The camera pair, `(reference, target)`; a target left of the
        /// reference is a left-side pair.
        cameras: (usize, usize),
        /// Only the samples of this split (all for `None`).
        split: Option<Split>,
    },
}

impl PairSource {
    /// Every pair, in dataset order, with its ground truth where there is
    /// one. The views' folders must exist; the files are read later.
    pub fn pairs(&self) -> Result<Vec<StereoPair>, DatasetError> {
        match self {
            PairSource::Single { left, right } => Ok(vec![StereoPair {
                id: left
                    .file_stem()
                    .map_or_else(|| "pair".into(), |s| s.to_string_lossy().into_owned()),
                cameras: (0, 1),
                reference: left.clone(),
                target: right.clone(),
                side: Side::Right,
                truth: None,
                disparity_bound: None,
            }]),
            PairSource::Kitti { dir, frames } => {
                kitti_view_pairs(&KittiFolder::open(dir)?, *frames)
            }
            PairSource::Benchmark { benchmark, dir } => match benchmark {
                Benchmark::Kitti => {
                    kitti_view_pairs(&KittiFolder::open(dir)?, KittiFrames::Benchmark)
                }
                Benchmark::Middlebury | Benchmark::Eth3d => two_view_pairs(dir, *benchmark),
                Benchmark::DrivingStereo => driving_stereo_pairs(dir),
                Benchmark::SceneFlow => scene_flow_pairs(dir),
            },
            PairSource::Manifest {
                path,
                cameras,
                split,
            } => {
                let manifest = Manifest::load(path)?;
                manifest_pairs(path, &manifest, &[*cameras], *split)
            }
        }
    }

    /// The pairs with ground truth; an error naming the dataset when there
    /// is none. A KITTI folder's pairs are those of its ground-truth folder,
    /// whose views need not be there (a folder of ground truth alone
    /// scores predictions).
    pub fn scored_pairs(&self) -> Result<Vec<StereoPair>, DatasetError> {
        let (pairs, path, none) = match self {
            PairSource::Single { left, .. } => (Vec::new(), left, "no ground truth".to_string()),
            PairSource::Kitti { dir, .. }
            | PairSource::Benchmark {
                benchmark: Benchmark::Kitti,
                dir,
            } => (kitti_truth_pairs(dir)?, dir, "no ground truth".to_string()),
            PairSource::Benchmark { benchmark, dir } => (
                self.pairs()?,
                dir,
                format!("no frame has {benchmark}'s ground truth"),
            ),
            PairSource::Manifest {
                path,
                cameras: (r, t),
                split,
            } => {
                let of_split = split.map_or(String::new(), |s| format!(" of the {s:?} split"));
                let none = format!("no sample{of_split} has ground truth for pair {r}:{t}");
                (self.pairs()?, path, none)
            }
        };
        let scored: Vec<StereoPair> = pairs.into_iter().filter(|p| p.truth.is_some()).collect();
        if scored.is_empty() {
            return Err(DatasetError::Layout {
                path: path.clone(),
                message: none,
            });
        }
        Ok(scored)
    }
}

/// The view `k` of `sample`, resolved against the manifest's folder.
pub fn sample_view(path: &Path, sample: &Sample, k: usize) -> Result<PathBuf, DatasetError> {
    sample
        .views
        .get(k)
        .map(|v| resolve(path, v))
        .ok_or_else(|| DatasetError::Manifest {
            path: path.to_path_buf(),
            message: format!("sample {} has no view {k}", sample.id),
        })
}

/// The pair `(reference, target)` of `sample` with its ground truth, if
/// the manifest has one. `path` is the manifest's file.
pub fn sample_pair(
    path: &Path,
    sample: &Sample,
    (reference, target): (usize, usize),
) -> Result<StereoPair, DatasetError> {
    let truth = sample
        .ground_truth
        .iter()
        .find(|g| g.reference == reference && g.target == target)
        .map(|gt| GroundTruthFile {
            disparity: resolve(path, &gt.disparity),
            scale: gt.scale as f32,
            noc: gt
                .occlusion
                .as_deref()
                .map(|o| NocSource::Occlusion(resolve(path, o))),
        });
    Ok(StereoPair {
        id: sample.id.clone(),
        cameras: (reference, target),
        reference: sample_view(path, sample, reference)?,
        target: sample_view(path, sample, target)?,
        side: if target > reference {
            Side::Right
        } else {
            Side::Left
        },
        truth,
        disparity_bound: None,
    })
}

/// The pairs `cameras` of every sample of `split` (all samples for `None`)
/// of the manifest `manifest` read from `path`, sample by sample. A camera
/// outside the rig is an error.
pub fn manifest_pairs(
    path: &Path,
    manifest: &Manifest,
    cameras: &[(usize, usize)],
    split: Option<Split>,
) -> Result<Vec<StereoPair>, DatasetError> {
    check_cameras(path, manifest, cameras)?;
    let mut pairs = Vec::new();
    for sample in manifest
        .samples
        .iter()
        .filter(|s| split.is_none_or(|split| s.split == split))
    {
        for &pair in cameras {
            pairs.push(sample_pair(path, sample, pair)?);
        }
    }
    Ok(pairs)
}

/// Refuses camera pairs that do not fit the manifest's rig.
pub fn check_cameras(
    path: &Path,
    manifest: &Manifest,
    cameras: &[(usize, usize)],
) -> Result<(), DatasetError> {
    let views = manifest.rig.num_views;
    match cameras
        .iter()
        .find(|&&(r, t)| r >= views || t >= views || r == t)
    {
        Some((r, t)) => Err(DatasetError::Manifest {
            path: path.to_path_buf(),
            message: format!("pair {r}:{t} does not fit the rig's {views} cameras"),
        }),
        None => Ok(()),
    }
}

/// The ground truth of a KITTI frame, from the folder names of `version`
/// under `dir`, when the all-pixels map exists.
fn kitti_truth(dir: &Path, version: KittiVersion, frame: &str) -> Option<GroundTruthFile> {
    let (occ, noc) = version.gt_dirs();
    let file = format!("{frame}.png");
    let disparity = dir.join(occ).join(&file);
    let noc = dir.join(noc).join(&file);
    disparity.is_file().then(|| GroundTruthFile {
        disparity,
        scale: 1.0,
        noc: noc.is_file().then_some(NocSource::Map(noc)),
    })
}

/// The frames of a KITTI folder's view folders as pairs.
fn kitti_view_pairs(
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
            truth: kitti_truth(&folder.root, folder.version, f),
            disparity_bound: None,
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
fn kitti_truth_pairs(dir: &Path) -> Result<Vec<StereoPair>, DatasetError> {
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
                truth: kitti_truth(dir, version, &stem),
                disparity_bound: None,
                id: stem,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_test_support::files::touch;

    fn kitti(dir: &Path) -> PairSource {
        PairSource::Kitti {
            dir: dir.to_path_buf(),
            frames: KittiFrames::Benchmark,
        }
    }

    #[test]
    fn kitti_ground_truth_is_listed_with_noc_maps_where_present() {
        let dir = tempfile::tempdir().unwrap();
        touch(&dir.path().join("disp_occ_0/000001_10.png"));
        touch(&dir.path().join("disp_occ_0/000000_10.png"));
        touch(&dir.path().join("disp_noc_0/000001_10.png"));
        let pairs = kitti(dir.path()).scored_pairs().unwrap();
        let ids: Vec<&str> = pairs.iter().map(|p| p.id.as_str()).collect();
        assert_eq!(ids, ["000000_10", "000001_10"]);
        assert_eq!(pairs[0].truth.as_ref().unwrap().noc, None);
        assert_eq!(
            pairs[1].truth.as_ref().unwrap().noc,
            Some(NocSource::Map(dir.path().join("disp_noc_0/000001_10.png")))
        );
        assert_eq!(pairs[1].reference, dir.path().join("image_2/000001_10.png"));
        let err = kitti(&dir.path().join("image_2"))
            .scored_pairs()
            .unwrap_err();
        assert!(err.to_string().contains("expected disp_occ_0"), "{err}");
    }

    #[test]
    fn kitti_views_give_all_frames_or_the_benchmark_ones() {
        let dir = tempfile::tempdir().unwrap();
        let err = kitti(dir.path()).pairs().unwrap_err().to_string();
        assert!(err.contains("not a KITTI folder"), "{err}");
        touch(&dir.path().join("colored_0/000001_10.png"));
        touch(&dir.path().join("colored_0/000001_11.png"));
        touch(&dir.path().join("disp_occ/000001_10.png"));
        std::fs::create_dir_all(dir.path().join("colored_1")).unwrap();
        let pairs = kitti(dir.path()).pairs().unwrap();
        assert_eq!(pairs.len(), 1);
        assert_eq!(pairs[0].id, "000001_10");
        assert_eq!(pairs[0].target, dir.path().join("colored_1/000001_10.png"));
        let truth = pairs[0].truth.as_ref().unwrap();
        assert_eq!(truth.disparity, dir.path().join("disp_occ/000001_10.png"));
        let all = PairSource::Kitti {
            dir: dir.path().to_path_buf(),
            frames: KittiFrames::All,
        }
        .pairs()
        .unwrap();
        assert_eq!(all.len(), 2);
        assert_eq!(all[1].truth, None);
    }

    #[test]
    fn one_pair_is_named_after_its_left_view_and_has_no_ground_truth() {
        let source = PairSource::Single {
            left: "a/im2.png".into(),
            right: "a/im6.png".into(),
        };
        let pairs = source.pairs().unwrap();
        assert_eq!(pairs[0].id, "im2");
        assert_eq!(pairs[0].side, Side::Right);
        let err = source.scored_pairs().unwrap_err().to_string();
        assert_eq!(err, "a/im2.png: no ground truth");
    }
}
