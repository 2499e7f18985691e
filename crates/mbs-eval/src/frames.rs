//! The frames a frame list names (`--frames`, a Python list): pair ids
//! such as KITTI `000000_10`, a Middlebury or ETH3D scene folder, a
//! DrivingStereo frame stem, a SceneFlow `TEST/A/0000/0006` or a manifest
//! sample id.

use std::path::{Path, PathBuf};

use crate::error::EvalError;

/// The frames a list names.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameList {
    /// The file the names come from (what messages call the list).
    pub path: PathBuf,
    /// The names, in list order.
    pub names: Vec<String>,
}

impl FrameList {
    /// Reads a list: one name a line, surrounding blanks trimmed, blank
    /// lines and `#` comments (to the end of the line) ignored. A list
    /// without a name is an error naming the file.
    pub fn read(path: &Path) -> Result<FrameList, EvalError> {
        let text =
            mbs_core::regular::read_text(path).map_err(|source| EvalError::ReadFrameList {
                path: path.to_path_buf(),
                source,
            })?;
        FrameList::from_names(path.to_path_buf(), mbs_core::list_file::list_entries(&text))
    }

    /// A list of `names` (blanks trimmed, empty names dropped) that
    /// messages call `path`; an error when no name is left.
    pub fn from_names(
        path: PathBuf,
        names: impl IntoIterator<Item = String>,
    ) -> Result<FrameList, EvalError> {
        let names: Vec<String> = names
            .into_iter()
            .map(|n| n.trim().to_string())
            .filter(|n| !n.is_empty())
            .collect();
        if names.is_empty() {
            return Err(EvalError::EmptyFrameList(path));
        }
        Ok(FrameList { path, names })
    }

    /// Whether `name` is listed.
    pub fn contains(&self, name: &str) -> bool {
        self.names.iter().any(|n| n == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_lists_skip_blanks_and_comments() {
        let text = "# KITTI 2012 train_all\n000000_10\n\n  000001_10  # second\r\n#000002_10\n";
        assert_eq!(
            mbs_core::list_file::list_entries(text),
            ["000000_10", "000001_10"]
        );
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
    fn a_list_of_names_keeps_its_names_and_refuses_none() {
        let names = [" a ".to_string(), String::new(), "b".to_string()];
        let list = FrameList::from_names("frames".into(), names).unwrap();
        assert_eq!(list.names, ["a", "b"]);
        let err = FrameList::from_names("frames".into(), Vec::new()).unwrap_err();
        assert_eq!(err.to_string(), "frames: the frame list names no frame");
        let missing = FrameList::read(Path::new("/no/such/list.txt")).unwrap_err();
        assert_eq!(
            missing.to_string(),
            "reading the frame list /no/such/list.txt"
        );
        assert!(std::error::Error::source(&missing).is_some());
    }
}
