//! The files a command reads, so that none of its outputs replaces one: an
//! output path is compared with every input by file identity (device and
//! inode on Unix, so another spelling, a link or a hard link to an input is
//! caught; the resolved path elsewhere), before anything is written.

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

use crate::error::{FormatError, Result};

/// What identifies a file on disk: device and inode.
#[cfg(unix)]
type FileId = (u64, u64);

/// What identifies a file on disk: its resolved path.
#[cfg(not(unix))]
type FileId = PathBuf;

/// The identity of the existing file `path` (links followed).
#[cfg(unix)]
fn identity(path: &Path) -> Option<FileId> {
    use std::os::unix::fs::MetadataExt;
    let metadata = fs::metadata(path).ok()?;
    Some((metadata.dev(), metadata.ino()))
}

/// The identity of the existing file `path` (links followed).
#[cfg(not(unix))]
fn identity(path: &Path) -> Option<FileId> {
    fs::canonicalize(path).ok()
}

/// Whether `a` and `b` are one existing file (by identity: another
/// spelling, a link or a hard link to it is the same file).
pub fn same_file(a: &Path, b: &Path) -> bool {
    matches!((identity(a), identity(b)), (Some(x), Some(y)) if x == y)
}

/// The files a command reads.
#[derive(Debug, Default)]
pub struct InputFiles {
    /// The inputs by identity, with the name the command read each under.
    by_identity: HashMap<FileId, PathBuf>,
}

impl InputFiles {
    /// No inputs yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records `path` as an input; a missing file records nothing (the
    /// command reports it when it reads it).
    pub fn add(&mut self, path: &Path) {
        if let Some(id) = identity(path) {
            self.by_identity.insert(id, path.to_path_buf());
        }
    }

    /// An input that lies inside the folder `dir`, if any: for outputs
    /// that replace or prune whole folders. The folder is walked (its
    /// links to folders not followed, so a loop cannot stall it) and each
    /// file looked up by identity.
    pub fn inside(&self, dir: &Path) -> Option<&Path> {
        let entries = fs::read_dir(dir).ok()?;
        entries.flatten().find_map(|entry| {
            let path = entry.path();
            match entry.file_type() {
                Ok(kind) if kind.is_dir() => self.inside(&path),
                Ok(_) => self
                    .by_identity
                    .get(&identity(&path)?)
                    .map(PathBuf::as_path),
                Err(_) => None,
            }
        })
    }

    /// The input `output` would replace, if any.
    fn clash(&self, output: &Path) -> Option<&Path> {
        let input = self.by_identity.get(&identity(output)?)?;
        Some(input)
    }

    /// Refuses an `output` that is one of the inputs, naming both.
    pub fn refuse(&self, output: &Path) -> Result<()> {
        match self.clash(output) {
            None => Ok(()),
            Some(input) => Err(FormatError::invalid(
                output,
                format!(
                    "is {}, which this command reads; refusing to replace an input \
                     (choose another output)",
                    describe_input(output, input)
                ),
            )),
        }
    }
}

impl<P: AsRef<Path>> Extend<P> for InputFiles {
    /// Records every path as an input ([`InputFiles::add`]).
    fn extend<I: IntoIterator<Item = P>>(&mut self, paths: I) {
        paths.into_iter().for_each(|path| self.add(path.as_ref()));
    }
}

/// How an output that clashes with `input` is said to be it.
fn describe_input(output: &Path, input: &Path) -> String {
    if output == input {
        "one of its inputs".into()
    } else {
        format!("the input {}", input.display())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_input_under_any_name_is_refused_and_others_pass() {
        let dir = tempfile::tempdir().unwrap();
        let truth = dir.path().join("disp0GT.pfm");
        fs::write(&truth, b"PF").unwrap();
        let mut inputs = InputFiles::new();
        inputs.add(&truth);
        inputs.add(&dir.path().join("missing.png"));
        let err = inputs.refuse(&truth).unwrap_err().to_string();
        assert!(err.contains("disp0GT.pfm: is one of its inputs"), "{err}");
        // The same file by another path, a link and a hard link; a file
        // that is not an input passes.
        fs::write(dir.path().join("other.pfm"), b"other").unwrap();
        assert!(inputs.refuse(&dir.path().join("other.pfm")).is_ok());
        let dotted = dir.path().join(".").join("disp0GT.pfm");
        let link = dir.path().join("link.pfm");
        let hard = dir.path().join("hard.pfm");
        #[cfg(unix)]
        std::os::unix::fs::symlink(&truth, &link).unwrap();
        fs::hard_link(&truth, &hard).unwrap();
        for other in [&dotted, &link, &hard] {
            if !other.exists() {
                continue;
            }
            let err = inputs.refuse(other).unwrap_err().to_string();
            assert!(err.contains("refusing to replace an input"), "{err}");
        }
        assert!(inputs.refuse(&dir.path().join("disp0MBS.pfm")).is_ok());
        assert!(inputs.refuse(&dir.path().join("missing.png")).is_ok());
    }

    #[test]
    fn inputs_inside_a_folder_are_found_and_hard_links_are_the_same_file() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("run");
        let step = run.join("checkpoints/step-1");
        fs::create_dir_all(&step).unwrap();
        let teacher = step.join("teacher.bpk");
        fs::write(&teacher, b"weights").unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(&run, run.join("checkpoints/loop")).unwrap();
        let mut inputs = InputFiles::new();
        inputs.add(&teacher);
        let inside = inputs.inside(&run.join("checkpoints")).unwrap();
        assert!(inside.ends_with("teacher.bpk"), "{}", inside.display());
        assert!(inputs.inside(&run.join("elsewhere")).is_none());
        let hard = dir.path().join("hard.bpk");
        fs::hard_link(&teacher, &hard).unwrap();
        assert!(same_file(&teacher, &hard));
        assert!(!same_file(&teacher, &dir.path().join("missing")));
    }
}
