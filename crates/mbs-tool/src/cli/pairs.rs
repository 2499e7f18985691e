//! Which stereo pairs a command works on: one pair of files, a benchmark's
//! folder (KITTI, Middlebury, ETH3D, DrivingStereo, SceneFlow) or one
//! camera pair of a manifest (`REFERENCE:TARGET`, e.g. `0:4`), as flags
//! shared by `predict` and `eval` and turned into a [`PairSource`].

use std::path::PathBuf;

use mbs_dataset::Split;
use mbs_dataset::pairs::PairSource;
use serde_json::Value;

use super::folders::{self, AnyOne, BenchmarkFolders};

/// The flags that choose the pairs.
#[derive(clap::Args)]
pub struct PairArgs {
    /// Left (reference) view of a single pair.
    #[arg(long, requires = "right", conflicts_with_all = [folders::GROUP, "manifest"])]
    pub left: Option<PathBuf>,
    /// Right (target) view of a single pair.
    #[arg(long, requires = "left")]
    pub right: Option<PathBuf>,
    /// A benchmark's folder (one).
    #[command(flatten)]
    pub folders: BenchmarkFolders<AnyOne>,
    /// A dataset manifest: every sample's --pair.
    #[arg(long, conflicts_with = folders::GROUP)]
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
        if let (Some(left), Some(right)) = (&self.left, &self.right) {
            super::require_file(left, "left view")?;
            super::require_file(right, "right view")?;
            return Ok(Some(PairSource::Single {
                left: left.clone(),
                right: right.clone(),
            }));
        }
        if let Some((benchmark, dir)) = self.folders.first() {
            return Ok(Some(PairSource::Benchmark {
                benchmark,
                dir: dir.clone(),
            }));
        }
        Ok(self.manifest.as_ref().map(|path| PairSource::Manifest {
            path: path.clone(),
            cameras: self.pair,
            split: self.split,
        }))
    }
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
