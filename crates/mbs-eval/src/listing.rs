//! What a source has to score: its pairs with ground truth (only a frame
//! list's, when one is given), and its frames without usable ground truth,
//! which are named rather than silently left out.

use std::collections::HashSet;

use mbs_dataset::pairs::PairSource;
use mbs_dataset::{DatasetError, StereoPair};

use crate::error::EvalError;
use crate::frames::FrameList;

/// A source's pairs with ground truth, and its frames without.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Listing {
    /// The pairs with ground truth, in dataset order.
    pub pairs: Vec<StereoPair>,
    /// The frames whose ground truth is missing or is not a regular file
    /// (a folder, a FIFO), which are not scored.
    pub unscored: Vec<String>,
    /// Every frame name of the source, scored or not.
    pub frames: HashSet<String>,
}

impl Listing {
    /// The pairs of `source` with ground truth, and the names of its
    /// frames without (its views' frames that are not among them; none
    /// when the views cannot be listed, e.g. a KITTI folder of ground
    /// truth alone).
    pub fn of(source: &PairSource) -> Result<Listing, DatasetError> {
        let pairs = source.scored_pairs()?;
        let scored: HashSet<&str> = pairs.iter().map(|p| p.id.as_str()).collect();
        let every = source.pairs().unwrap_or_default();
        let unscored: Vec<String> = every
            .iter()
            .filter(|p| !scored.contains(p.id.as_str()))
            .map(|p| p.id.clone())
            .collect();
        let frames = every
            .into_iter()
            .map(|p| p.id)
            .chain(scored.iter().map(|s| s.to_string()));
        Ok(Listing {
            frames: frames.collect(),
            pairs,
            unscored,
        })
    }

    /// Only the frames `list` names.
    pub fn keep(self, list: &FrameList) -> Listing {
        Listing {
            pairs: self
                .pairs
                .into_iter()
                .filter(|p| list.contains(&p.id))
                .collect(),
            unscored: self
                .unscored
                .into_iter()
                .filter(|name| list.contains(name))
                .collect(),
            frames: self.frames,
        }
    }
}

/// The frame list's names that none of `listings` has: an error naming
/// them and the list, with `places` saying where they were looked for.
pub fn check_listed(
    list: &FrameList,
    listings: &[&Listing],
    places: &str,
) -> Result<(), EvalError> {
    let missing: Vec<String> = list
        .names
        .iter()
        .filter(|name| !listings.iter().any(|l| l.frames.contains(*name)))
        .cloned()
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    Err(EvalError::Unlisted {
        list: list.path.clone(),
        places: places.to_string(),
        missing,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(frames: &[&str]) -> Listing {
        Listing {
            frames: frames.iter().map(|f| f.to_string()).collect(),
            unscored: vec!["b".into(), "c".into()],
            ..Listing::default()
        }
    }

    #[test]
    fn a_list_keeps_its_frames_and_names_those_found_nowhere() {
        let list =
            FrameList::from_names("l.txt".into(), ["a".to_string(), "b".to_string()]).unwrap();
        assert_eq!(listing(&["a", "b", "c"]).keep(&list).unscored, ["b"]);
        assert!(check_listed(&list, &[&listing(&["a"]), &listing(&["b"])], "x").is_ok());
        let err = check_listed(&list, &[&listing(&["a"])], "k or m").unwrap_err();
        assert_eq!(
            err.to_string(),
            "l.txt: 1 listed frame(s) not found in k or m: b"
        );
    }
}
