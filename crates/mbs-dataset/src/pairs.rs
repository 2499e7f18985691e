//! Stereo pairs wherever they come from: one pair of files, a benchmark's
//! folder (KITTI, Middlebury, ETH3D, DrivingStereo, SceneFlow) or one
//! camera pair of a manifest's samples, each with its ground truth when
//! the dataset has it. `predict`, `eval`, `extrapolate` and the
//! trainer's validation all list their pairs here.

use std::path::{Path, PathBuf};

use mbs_core::Side;
use mbs_core::inputs::InputFiles;

use crate::DatasetError;
use crate::benchmark::{Benchmark, Dataset};
use crate::ground_truth::{GroundTruthFile, NocSource};
use crate::kitti::{self, KittiFolder, KittiFrames};
use crate::manifest::{Manifest, Sample, Split, resolve};
use crate::stereo_pair::StereoPair;

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
                calibration: None,
            }]),
            PairSource::Kitti { dir, frames } => {
                kitti::view_pairs(&KittiFolder::open(dir)?, *frames)
            }
            PairSource::Benchmark { benchmark, dir } => (benchmark.layout().pairs)(dir),
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

    /// The dataset whose scoring rules the source's pairs follow: the
    /// benchmark (KITTI with its year), or other data for manifests and
    /// single pairs.
    pub fn dataset(&self) -> Dataset {
        match self {
            PairSource::Kitti { dir, .. } => Benchmark::Kitti.dataset(dir),
            PairSource::Benchmark { benchmark, dir } => benchmark.dataset(dir),
            PairSource::Single { .. } | PairSource::Manifest { .. } => Dataset::Other,
        }
    }

    /// Where the source's frames are, for messages: its folder, its
    /// manifest or its left view.
    pub fn place(&self) -> &Path {
        match self {
            PairSource::Single { left, .. } => left,
            PairSource::Kitti { dir, .. } | PairSource::Benchmark { dir, .. } => dir,
            PairSource::Manifest { path, .. } => path,
        }
    }

    /// Every file a command reading `pairs` (this source's) reads or may
    /// read: each pair's files, and for a manifest the manifest itself and
    /// every file of every sample it lists, not only the pair's two views.
    pub fn input_files(&self, pairs: &[StereoPair]) -> Result<InputFiles, DatasetError> {
        let mut inputs = crate::stereo_pair::input_files(pairs);
        if let PairSource::Manifest { path, .. } = self {
            inputs.add(path);
            let manifest = Manifest::load(path)?;
            inputs.extend(manifest_files(path, &manifest));
        }
        Ok(inputs)
    }

    /// The pairs with ground truth; an error naming the dataset when there
    /// is none. A KITTI folder's pairs are those of its ground-truth folder,
    /// whose views need not be there (a folder of ground truth alone
    /// scores predictions).
    pub fn scored_pairs(&self) -> Result<Vec<StereoPair>, DatasetError> {
        let (pairs, path, none) = match self {
            PairSource::Single { left, .. } => (Vec::new(), left, "no ground truth".to_string()),
            PairSource::Kitti { dir, .. } => {
                (kitti::truth_pairs(dir)?, dir, "no ground truth".to_string())
            }
            PairSource::Benchmark { benchmark, dir } => (
                (benchmark.layout().scored_pairs)(dir)?,
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
        calibration: None,
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

/// Every file `manifest`'s samples name (views, depth, ground truth,
/// masks...), resolved against its file `path`.
pub fn manifest_files(path: &Path, manifest: &Manifest) -> Vec<PathBuf> {
    manifest
        .samples
        .iter()
        .flat_map(Sample::files)
        .map(|(_, file)| resolve(path, file))
        .collect()
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

    /// Every frame's non-occluded map is in `disp_noc_0` when the folder
    /// is there (000000_10's is missing: loading it is an error, see
    /// `kitti`'s tests).
    #[test]
    fn kitti_ground_truth_is_listed_with_the_noc_folder_maps() {
        let dir = tempfile::tempdir().unwrap();
        touch(&dir.path().join("disp_occ_0/000001_10.png"));
        touch(&dir.path().join("disp_occ_0/000000_10.png"));
        touch(&dir.path().join("disp_noc_0/000001_10.png"));
        let pairs = kitti(dir.path()).scored_pairs().unwrap();
        let ids: Vec<&str> = pairs.iter().map(|p| p.id.as_str()).collect();
        assert_eq!(ids, ["000000_10", "000001_10"]);
        assert_eq!(
            pairs[0].truth.as_ref().unwrap().noc,
            Some(NocSource::Map(dir.path().join("disp_noc_0/000000_10.png")))
        );
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

    #[test]
    fn each_source_names_its_rules_data_and_its_place() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("disp_occ")).unwrap();
        assert_eq!(kitti(dir.path()).dataset(), Dataset::Kitti2012);
        assert_eq!(kitti(dir.path()).place(), dir.path());
        let eth3d = PairSource::Benchmark {
            benchmark: Benchmark::Eth3d,
            dir: dir.path().join("two_view_training"),
        };
        assert_eq!(eth3d.dataset(), Dataset::Eth3d);
        let manifest = PairSource::Manifest {
            path: PathBuf::from("m/manifest.json"),
            cameras: (0, 1),
            split: None,
        };
        assert_eq!(manifest.dataset(), Dataset::Other);
        assert_eq!(manifest.place(), Path::new("m/manifest.json"));
        let single = PairSource::Single {
            left: PathBuf::from("l.png"),
            right: PathBuf::from("r.png"),
        };
        assert_eq!(
            (single.dataset(), single.place()),
            (Dataset::Other, Path::new("l.png"))
        );
    }
}
