//! The public stereo benchmarks whose folders mbs reads as their downloads
//! unpack, and the one table ([`Benchmark::layout`]) that says how: the
//! flag that names a folder, what the folder holds, how its pairs are
//! listed and which rules' data it is ([`Dataset`]: what a scoring
//! protocol is applied to). A new layout is its module, its test and one
//! row here. How each is scored (its threshold, the paper's Table 4's
//! included) is `mbs_eval::Protocol`'s business.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

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

/// What a protocol is applied to: its rules depend on the benchmark.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Dataset {
    /// KITTI 2015 (`disp_occ_0`, `disp_noc_0`).
    Kitti2015,
    /// KITTI 2012 (`disp_occ`, `disp_noc`).
    Kitti2012,
    /// Middlebury 2014 / MiddEval3.
    Middlebury,
    /// ETH3D two-view.
    Eth3d,
    /// DrivingStereo.
    DrivingStereo,
    /// SceneFlow (FlyingThings3D, Driving, Monkaa).
    SceneFlow,
    /// Anything else: a manifest, a single ground-truth file.
    Other,
}

impl Dataset {
    /// Every dataset, in table order.
    pub const EVERY: [Dataset; 7] = [
        Dataset::Kitti2015,
        Dataset::Kitti2012,
        Dataset::Middlebury,
        Dataset::Eth3d,
        Dataset::DrivingStereo,
        Dataset::SceneFlow,
        Dataset::Other,
    ];

    /// The name tables and messages use.
    pub fn name(self) -> &'static str {
        match self {
            Dataset::Kitti2015 => "KITTI 2015",
            Dataset::Kitti2012 => "KITTI 2012",
            Dataset::Middlebury => "Middlebury",
            Dataset::Eth3d => "ETH3D",
            Dataset::DrivingStereo => "DrivingStereo",
            Dataset::SceneFlow => "SceneFlow",
            Dataset::Other => "other data",
        }
    }

    /// The dataset's key, as settings and bindings name it (`kitti2015`,
    /// `kitti2012`, `middlebury`, `eth3d`, `drivingstereo`, `sceneflow`,
    /// `other`); [`Dataset::from_str`] reads it back.
    pub fn key(self) -> &'static str {
        match self {
            Dataset::Kitti2015 => "kitti2015",
            Dataset::Kitti2012 => "kitti2012",
            Dataset::Middlebury => "middlebury",
            Dataset::Eth3d => "eth3d",
            Dataset::DrivingStereo => "drivingstereo",
            Dataset::SceneFlow => "sceneflow",
            Dataset::Other => "other",
        }
    }
}

impl FromStr for Dataset {
    type Err = UnknownName;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Dataset::EVERY
            .into_iter()
            .find(|d| d.key() == text)
            .ok_or_else(|| UnknownName::new(text, "dataset", Dataset::EVERY.map(Dataset::key)))
    }
}

/// A name that is not one of its kind's ([`Dataset::from_str`],
/// [`Benchmark::from_str`]), with the names there are.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{name}` is not a {kind}: {choices}")]
pub struct UnknownName {
    /// The name given.
    pub name: String,
    /// What it should have named (`dataset`, `benchmark`).
    pub kind: &'static str,
    /// The names there are, in words (`a, b or c`).
    pub choices: String,
}

impl UnknownName {
    /// `name`, which is none of `names` of `kind`.
    pub fn new<const N: usize>(name: &str, kind: &'static str, names: [&str; N]) -> UnknownName {
        let choices = match names.split_last() {
            Some((last, [])) => last.to_string(),
            Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
            None => String::new(),
        };
        UnknownName {
            name: name.to_string(),
            kind,
            choices,
        }
    }
}

impl fmt::Display for Dataset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
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

    /// Whose scoring rules the pairs of the folder `dir` follow (KITTI:
    /// the year its ground-truth folders name).
    pub fn dataset(self, dir: &Path) -> Dataset {
        (self.layout().dataset)(dir)
    }

    /// The name of the folder `dir` of this benchmark in tables: the
    /// benchmark (KITTI with its year) and the folder's name, e.g.
    /// `KITTI 2015 training` or `DrivingStereo rainy`.
    pub fn label(self, dir: &Path) -> String {
        let name = dir.file_name().map_or_else(
            || dir.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        match self.dataset(dir) {
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

impl FromStr for Benchmark {
    type Err = UnknownName;

    /// A benchmark by its flag's name (`kitti`, `middlebury`, `eth3d`,
    /// `drivingstereo`, `sceneflow`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Benchmark::ALL
            .into_iter()
            .find(|b| b.layout().flag == text)
            .ok_or_else(|| {
                UnknownName::new(text, "benchmark", Benchmark::ALL.map(|b| b.layout().flag))
            })
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

    #[test]
    fn benchmarks_and_datasets_parse_back_from_their_names() {
        for benchmark in Benchmark::ALL {
            assert_eq!(benchmark.layout().flag.parse(), Ok(benchmark));
        }
        for dataset in Dataset::EVERY {
            assert_eq!(dataset.key().parse(), Ok(dataset));
        }
        let err = "KITTI".parse::<Benchmark>().unwrap_err();
        assert_eq!(
            err.to_string(),
            "`KITTI` is not a benchmark: kitti, middlebury, eth3d, drivingstereo or sceneflow"
        );
        let err = "kitti".parse::<Dataset>().unwrap_err();
        assert_eq!(
            err.to_string(),
            "`kitti` is not a dataset: kitti2015, kitti2012, middlebury, eth3d, drivingstereo, \
             sceneflow or other"
        );
    }

    #[test]
    fn a_folder_follows_its_benchmarks_rules() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("disp_occ_0")).unwrap();
        assert_eq!(Benchmark::Kitti.dataset(dir.path()), Dataset::Kitti2015);
        assert_eq!(Benchmark::Kitti.dataset(Path::new("/none")), Dataset::Other);
        assert_eq!(
            Benchmark::Middlebury.dataset(Path::new("/none")),
            Dataset::Middlebury
        );
    }
}
