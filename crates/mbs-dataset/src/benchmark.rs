//! The public stereo benchmarks whose folders mbs reads as their downloads
//! unpack, and the one table ([`Benchmark::layout`]) that says how: the
//! flag that names a folder, what the folder holds, how its pairs are
//! listed and which rules' data it is. A new layout is its module, its
//! test and one row here. How each is scored (its threshold, the paper's
//! Table 4's included) is `mbs_core::metrics::Protocol`'s business.

use std::fmt;
use std::path::Path;

use mbs_core::metrics::Dataset;

use crate::DatasetError;
use crate::kitti::{self, KittiVersion};
use crate::stereo_pair::StereoPair;
use crate::{driving_stereo, scene_flow, two_view};

/// A benchmark with a folder layout of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Benchmark {
    /// KITTI 2015 or 2012 ([`crate::kitti`]).
    Kitti,
    /// Middlebury 2014 / MiddEval3 ([`crate::two_view`]).
    Middlebury,
    /// ETH3D two-view ([`crate::two_view`]).
    Eth3d,
    /// DrivingStereo's weather subsets ([`crate::driving_stereo`]).
    DrivingStereo,
    /// SceneFlow: FlyingThings3D, Driving, Monkaa ([`crate::scene_flow`]).
    SceneFlow,
}

impl Benchmark {
    /// Every benchmark, in the order tables list them.
    pub const ALL: [Benchmark; 5] = [
        Benchmark::Kitti,
        Benchmark::Middlebury,
        Benchmark::Eth3d,
        Benchmark::DrivingStereo,
        Benchmark::SceneFlow,
    ];

    /// The benchmark's name, as tables and messages spell it.
    pub fn name(self) -> &'static str {
        match self {
            Benchmark::Kitti => "KITTI",
            Benchmark::Middlebury => "Middlebury",
            Benchmark::Eth3d => "ETH3D",
            Benchmark::DrivingStereo => "DrivingStereo",
            Benchmark::SceneFlow => "SceneFlow",
        }
    }
}

/// How mbs reads one benchmark's folders.
#[derive(Debug)]
pub struct Layout {
    /// The command-line flag that names such a folder, without its dashes.
    pub flag: &'static str,
    /// What such a folder holds (the flag's help).
    pub folder: &'static str,
    /// Every pair of a folder, in dataset order, with its ground truth
    /// where the folder has it.
    pub pairs: fn(&Path) -> Result<Vec<StereoPair>, DatasetError>,
    /// The pairs of a folder the benchmark's ground truth covers (KITTI:
    /// listed from its ground-truth folders, so the views need not be
    /// there); pairs without ground truth are dropped by the caller.
    pub scored_pairs: fn(&Path) -> Result<Vec<StereoPair>, DatasetError>,
    /// Whose scoring rules a folder's pairs follow (KITTI: the year its
    /// ground-truth folders name).
    pub dataset: fn(&Path) -> Dataset,
}

impl Benchmark {
    /// How the benchmark's folders are read: the table of layouts.
    pub fn layout(self) -> &'static Layout {
        match self {
            Benchmark::Kitti => &Layout {
                flag: "kitti",
                folder: "A KITTI 2015 (image_2, image_3, disp_occ_0, disp_noc_0) or 2012 \
                         (colored_0, colored_1, disp_occ, disp_noc) training or testing \
                         folder; its *_10.png frames are the pairs.",
                pairs: kitti::benchmark_pairs,
                scored_pairs: kitti::truth_pairs,
                dataset: kitti_dataset,
            },
            Benchmark::Middlebury => &Layout {
                flag: "middlebury",
                folder: "A Middlebury 2014 / MiddEval3 folder of scenes (e.g. \
                         MiddEval3/trainingH: <Scene>/im0.png, im1.png, disp0GT.pfm, \
                         mask0nocc.png, calib.txt); each scene is a pair.",
                pairs: two_view::middlebury_pairs,
                scored_pairs: two_view::middlebury_pairs,
                dataset: |_| Dataset::Middlebury,
            },
            Benchmark::Eth3d => &Layout {
                flag: "eth3d",
                folder: "An ETH3D two-view folder of scenes (two_view_training, its ground \
                         truth read from the sibling two_view_training_gt); each scene is a \
                         pair.",
                pairs: two_view::eth3d_pairs,
                scored_pairs: two_view::eth3d_pairs,
                dataset: |_| Dataset::Eth3d,
            },
            Benchmark::DrivingStereo => &Layout {
                flag: "drivingstereo",
                folder: "A DrivingStereo weather folder (sunny, cloudy, foggy, rainy: \
                         left-image-full-size, right-image-full-size, \
                         disparity-map-full-size, or the -half-size ones); each frame is a \
                         pair. No occlusion mask: only ALL is scored.",
                pairs: driving_stereo::driving_stereo_pairs,
                scored_pairs: driving_stereo::driving_stereo_pairs,
                dataset: |_| Dataset::DrivingStereo,
            },
            Benchmark::SceneFlow => &Layout {
                flag: "sceneflow",
                folder: "A SceneFlow folder (FlyingThings3D, Driving or Monkaa) holding \
                         frames_finalpass or frames_cleanpass with disparity/ beside it, or a \
                         folder inside a pass (e.g. frames_finalpass/TEST); each left/right \
                         frame is a pair.",
                pairs: scene_flow::scene_flow_pairs,
                scored_pairs: scene_flow::scene_flow_pairs,
                dataset: |_| Dataset::SceneFlow,
            },
        }
    }

    /// The name of the folder `dir` of this benchmark in tables: the
    /// benchmark (KITTI with its year) and the folder's name, e.g.
    /// `KITTI 2015 training` or `DrivingStereo rainy`.
    pub fn label(self, dir: &Path) -> String {
        let name = dir.file_name().map_or_else(
            || dir.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        match (self.layout().dataset)(dir) {
            Dataset::Other => format!("{self} {name}"),
            dataset => format!("{} {name}", dataset.name()),
        }
    }
}

/// The rules' data of a KITTI folder: its year, from the ground-truth
/// folders it holds (other data without them).
fn kitti_dataset(dir: &Path) -> Dataset {
    match KittiVersion::of_ground_truth(dir) {
        Some(KittiVersion::Kitti2015) => Dataset::Kitti2015,
        Some(KittiVersion::Kitti2012) => Dataset::Kitti2012,
        None => Dataset::Other,
    }
}

impl fmt::Display for Benchmark {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_benchmark_has_its_own_flag_and_label() {
        let flags: Vec<&str> = Benchmark::ALL.iter().map(|b| b.layout().flag).collect();
        assert_eq!(
            flags,
            ["kitti", "middlebury", "eth3d", "drivingstereo", "sceneflow"]
        );
        let dir = tempfile::tempdir().unwrap();
        let kitti = dir.path().join("training");
        std::fs::create_dir_all(kitti.join("disp_occ")).unwrap();
        assert_eq!(Benchmark::Kitti.label(&kitti), "KITTI 2012 training");
        assert_eq!(
            Benchmark::Kitti.label(&dir.path().join("testing")),
            "KITTI testing"
        );
        assert_eq!(
            Benchmark::DrivingStereo.label(Path::new("/d/rainy")),
            "DrivingStereo rainy"
        );
    }

    #[test]
    fn each_benchmark_has_its_name() {
        let names: Vec<String> = Benchmark::ALL.iter().map(|b| b.to_string()).collect();
        assert_eq!(
            names,
            ["KITTI", "Middlebury", "ETH3D", "DrivingStereo", "SceneFlow"]
        );
    }
}
