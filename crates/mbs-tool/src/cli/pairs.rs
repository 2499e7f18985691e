//! Which stereo pairs a command works on: one pair of files, a benchmark's
//! folder (KITTI, Middlebury, ETH3D, DrivingStereo, SceneFlow) or one
//! camera pair of a manifest (`REFERENCE:TARGET`, e.g. `0:4`), as flags
//! shared by `predict` and `eval` and turned into a [`PairSource`]; and
//! the lists of frames `eval` and `benchmark` score ([`FrameList`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};

use mbs_dataset::Split;
use mbs_dataset::benchmark::Benchmark;
use mbs_dataset::pairs::{KittiFrames, PairSource};
use serde_json::Value;

/// The flags that choose the pairs.
#[derive(clap::Args)]
pub struct PairArgs {
    /// Left (reference) view of a single pair.
    #[arg(long, requires = "right", conflicts_with_all = ["kitti", "middlebury", "eth3d", "drivingstereo", "sceneflow", "manifest"])]
    pub left: Option<PathBuf>,
    /// Right (target) view of a single pair.
    #[arg(long, requires = "left")]
    pub right: Option<PathBuf>,
    /// A KITTI 2015 (image_2, image_3, disp_occ_0, disp_noc_0) or 2012
    /// (colored_0, colored_1, disp_occ, disp_noc) training or testing
    /// folder; its *_10.png frames are the pairs.
    #[arg(long, conflicts_with_all = ["middlebury", "eth3d", "drivingstereo", "sceneflow", "manifest"])]
    pub kitti: Option<PathBuf>,
    /// A Middlebury 2014 / MiddEval3 folder of scenes (e.g.
    /// MiddEval3/trainingQ: <Scene>/im0.png, im1.png, disp0GT.pfm,
    /// mask0nocc.png); each scene is a pair.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["eth3d", "drivingstereo", "sceneflow", "manifest"])]
    pub middlebury: Option<PathBuf>,
    /// An ETH3D two-view folder of scenes (two_view_training, its ground
    /// truth read from the sibling two_view_training_gt); each scene is a pair.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["drivingstereo", "sceneflow", "manifest"])]
    pub eth3d: Option<PathBuf>,
    /// A DrivingStereo weather folder (e.g. sunny: left-image-full-size,
    /// right-image-full-size, disparity-map-full-size, or the -half-size
    /// ones); each frame is a pair. No occlusion mask: only ALL is scored.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["sceneflow", "manifest"])]
    pub drivingstereo: Option<PathBuf>,
    /// A SceneFlow folder (FlyingThings3D, Driving or Monkaa) holding
    /// frames_finalpass or frames_cleanpass with disparity/ beside it, or a
    /// folder inside a pass (e.g. frames_finalpass/TEST); each left/right
    /// frame is a pair.
    #[arg(long, value_name = "DIR", conflicts_with = "manifest")]
    pub sceneflow: Option<PathBuf>,
    /// A dataset manifest: every sample's --pair.
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// Camera pair of manifest samples, REFERENCE:TARGET; a target left of
    /// the reference is handled by mirroring.
    #[arg(long, default_value = "0:1", value_parser = parse_pair)]
    pub pair: (usize, usize),
    /// Only the manifest's samples of this split (train, val or test).
    #[arg(long, requires = "manifest", value_parser = parse_split)]
    pub split: Option<Split>,
}

impl PairArgs {
    /// The pairs the flags name (a single pair's views must be files), or
    /// `None` when no flag names any.
    pub fn source(&self) -> anyhow::Result<Option<PairSource>> {
        Ok(
            if let (Some(left), Some(right)) = (&self.left, &self.right) {
                super::require_file(left, "left view")?;
                super::require_file(right, "right view")?;
                Some(PairSource::Single {
                    left: left.clone(),
                    right: right.clone(),
                })
            } else if let Some(dir) = &self.kitti {
                Some(PairSource::Kitti {
                    dir: dir.clone(),
                    frames: KittiFrames::Benchmark,
                })
            } else if let Some((benchmark, dir)) = self.benchmark_folder() {
                Some(PairSource::Benchmark {
                    benchmark,
                    dir: dir.clone(),
                })
            } else {
                self.manifest.as_ref().map(|path| PairSource::Manifest {
                    path: path.clone(),
                    cameras: self.pair,
                    split: self.split,
                })
            },
        )
    }
}

impl PairArgs {
    /// The benchmark folder other than KITTI's the flags name, with its
    /// benchmark.
    fn benchmark_folder(&self) -> Option<(Benchmark, &PathBuf)> {
        [
            (Benchmark::Middlebury, &self.middlebury),
            (Benchmark::Eth3d, &self.eth3d),
            (Benchmark::DrivingStereo, &self.drivingstereo),
            (Benchmark::SceneFlow, &self.sceneflow),
        ]
        .into_iter()
        .find_map(|(benchmark, dir)| Some((benchmark, dir.as_ref()?)))
    }
}

/// The frames a `--frames` file lists, by name (pair ids: KITTI
/// `000000_10`, a Middlebury or ETH3D scene folder, a DrivingStereo frame
/// stem, a SceneFlow `TEST/A/0000/0006`, a manifest sample id).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameList {
    /// The file the names come from.
    pub path: PathBuf,
    /// The names, in file order.
    pub names: Vec<String>,
}

impl FrameList {
    /// Reads a list: one name a line, surrounding blanks trimmed, blank
    /// lines and `#` comments (to the end of the line) ignored. A list
    /// without a name is an error naming the file.
    pub fn read(path: &Path) -> anyhow::Result<FrameList> {
        let text = mbs_core::regular::read_text(path)
            .with_context(|| format!("reading the frame list {}", path.display()))?;
        let names = parse_frame_names(&text);
        if names.is_empty() {
            bail!("{}: the frame list names no frame", path.display());
        }
        Ok(FrameList {
            path: path.to_path_buf(),
            names,
        })
    }

    /// Whether `name` is listed.
    pub fn contains(&self, name: &str) -> bool {
        self.names.iter().any(|n| n == name)
    }
}

/// The names of a frame list's text (see [`FrameList::read`]).
fn parse_frame_names(text: &str) -> Vec<String> {
    text.lines()
        .map(|line| line.split('#').next().unwrap_or_default().trim())
        .filter(|name| !name.is_empty())
        .map(str::to_string)
        .collect()
}

/// A split by its manifest name (the names `Split` is serialised with).
pub fn parse_split(text: &str) -> Result<Split, String> {
    serde_json::from_value(Value::from(text))
        .map_err(|_| format!("`{text}` is not a split: train, val or test"))
}

/// Parses `R:T` into two distinct camera indices.
pub fn parse_pair(s: &str) -> Result<(usize, usize), String> {
    let usage = || format!("invalid pair {s:?}: expected REFERENCE:TARGET, e.g. 0:1");
    let (r, t) = s.split_once(':').ok_or_else(usage)?;
    let pair: (usize, usize) = (
        r.trim().parse().map_err(|_| usage())?,
        t.trim().parse().map_err(|_| usage())?,
    );
    if pair.0 == pair.1 {
        return Err(format!(
            "invalid pair {s:?}: reference and target must differ"
        ));
    }
    Ok(pair)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_parse_and_must_differ() {
        assert_eq!(parse_pair("2:1"), Ok((2, 1)));
        assert_eq!(parse_pair(" 0 : 4"), Ok((0, 4)));
        assert!(parse_pair("1:1").unwrap_err().contains("must differ"));
        assert!(
            parse_pair("21")
                .unwrap_err()
                .contains("expected REFERENCE:TARGET")
        );
        assert!(parse_pair("a:1").is_err());
    }

    #[test]
    fn frame_lists_skip_blanks_and_comments() {
        let text = "# KITTI 2012 train_all\n000000_10\n\n  000001_10  # second\r\n#000002_10\n";
        assert_eq!(parse_frame_names(text), ["000000_10", "000001_10"]);
        let dir = tempfile::tempdir().unwrap();
        let empty = dir.path().join("empty.txt");
        std::fs::write(&empty, "# nothing\n\n").unwrap();
        let err = FrameList::read(&empty).unwrap_err().to_string();
        assert!(
            err.contains("empty.txt: the frame list names no frame"),
            "{err}"
        );
        let list = dir.path().join("list.txt");
        std::fs::write(&list, "a\nb\n").unwrap();
        let list = FrameList::read(&list).unwrap();
        assert!(list.contains("b") && !list.contains("c"));
    }

    #[test]
    fn splits_parse_by_their_manifest_names() {
        assert_eq!(parse_split("train"), Ok(Split::Train));
        assert_eq!(parse_split("val"), Ok(Split::Val));
        assert_eq!(parse_split("test"), Ok(Split::Test));
        assert_eq!(
            parse_split("Test"),
            Err("`Test` is not a split: train, val or test".into())
        );
    }
}
