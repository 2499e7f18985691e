//! An output folder as a command holds it: made, locked for one process
//! (or one shard) at a time ([`crate::lock`]), cleared of the temporary
//! files killed runs left, and with a record of the files mbs wrote there,
//! [`RECORD_FILE`], so that a command replaces (`--overwrite`) or skips
//! (a resumed run) only its own earlier outputs. A file under an output's
//! name that the record does not list (a dataset's ground truth, a user's
//! file, or an output of an mbs older than the record) is refused, whatever
//! the flags, before anything is written.
//!
//! The record lists names relative to the folder, one a line, `/` between
//! segments; a name ending in `/` covers everything under it (a training
//! run's `checkpoints/`). A command records its outputs' names before it
//! writes them, so a crash between the two leaves a name without a file,
//! never a file of ours without its name.

use std::collections::HashSet;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::error::{FormatError, Result};
use crate::lock::{FolderLock, Share, open_own};

/// The record of the files mbs wrote in an output folder.
pub const RECORD_FILE: &str = ".mbs-written";

/// The names an output folder's record lists.
#[derive(Debug, Default)]
pub struct Written {
    /// The folder.
    root: PathBuf,
    /// Its record's names.
    names: HashSet<String>,
}

impl Written {
    /// The record of `root`, read without writing anything: empty when the
    /// folder or its record is absent.
    pub fn read(root: &Path) -> Result<Self> {
        let record = root.join(RECORD_FILE);
        let text = match fs::symlink_metadata(&record) {
            Ok(m) if m.file_type().is_symlink() => {
                return Err(FormatError::invalid(
                    &record,
                    "is a symbolic link; mbs never reads or writes its record through a link \
                     (remove it)",
                ));
            }
            Ok(_) => crate::regular::read_text(&record)?,
            Err(_) => String::new(),
        };
        Ok(Self {
            root: root.to_path_buf(),
            names: text.lines().map(str::to_string).collect(),
        })
    }

    /// Whether the record lists `path` (a file inside the folder), by
    /// name or under a listed folder.
    pub fn lists(&self, path: &Path) -> bool {
        let Some(name) = name_in(&self.root, path) else {
            return false;
        };
        self.names.contains(&name)
            || self.names.contains(&format!("{name}/"))
            || name
                .match_indices('/')
                .any(|(i, _)| self.names.contains(&name[..=i]))
    }

    /// Refuses an `output` that exists (also as a link, or a link to
    /// nothing) and that the record does not list.
    pub fn refuse_foreign(&self, output: &Path) -> Result<()> {
        if fs::symlink_metadata(output).is_err() || self.lists(output) {
            return Ok(());
        }
        Err(FormatError::invalid(
            output,
            format!(
                "exists, and mbs did not write it ({} does not list it): it may be a \
                 dataset's or your own file, so it is neither replaced nor taken as a \
                 finished output, whatever the flags; move it away or choose another \
                 output folder",
                self.root.join(RECORD_FILE).display()
            ),
        ))
    }
}

/// `path`'s name inside `root`, `/` between its segments; `None` outside.
fn name_in(root: &Path, path: &Path) -> Option<String> {
    let here = root.as_os_str().is_empty() || root == Path::new(".");
    let rest = match path.strip_prefix(root) {
        Ok(rest) => rest,
        Err(_) if here && path.is_relative() => path,
        Err(_) => return None,
    };
    let segments: Vec<String> = rest
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    (!segments.is_empty()).then(|| segments.join("/"))
}

/// An output folder held by this process.
#[derive(Debug)]
pub struct OutDir {
    /// What its record lists.
    written: Written,
    /// The record, open for appending, and the names this process added.
    record: Mutex<(fs::File, HashSet<String>)>,
    /// How many temporary files of killed runs were removed.
    removed_partials: usize,
    /// The folder's lock, held as long as this lives.
    _lock: FolderLock,
}

impl OutDir {
    /// Makes `root` (and its parents; a file in its place is refused),
    /// takes its lock for `share` as `holder` (e.g. "mbs-tool predict"),
    /// removes the temporary files killed runs left and opens its record.
    pub fn take(root: &Path, share: Share, holder: &str) -> Result<Self> {
        crate::confine::create_out_dir(root)?;
        let lock = FolderLock::take(root, share, holder)?;
        Self::with_lock(root, lock)
    }

    /// Makes the folder `root`, which must not exist yet (its parents are
    /// made), and takes it for `share`: refused when it appeared since the
    /// caller saw it absent (another process got there first).
    pub fn take_new(root: &Path, share: Share, holder: &str) -> Result<Self> {
        if let Some(parent) = root.parent().filter(|p| !p.as_os_str().is_empty()) {
            fs::create_dir_all(parent).map_err(|e| FormatError::io(parent, e))?;
        }
        fs::create_dir(root).map_err(|e| match e.kind() {
            std::io::ErrorKind::AlreadyExists => FormatError::invalid(
                root,
                "appeared while this command was starting (another process?); \
                 run it again once that one has ended",
            ),
            _ => FormatError::io(root, e),
        })?;
        let lock = FolderLock::take(root, share, holder)?;
        Self::with_lock(root, lock)
    }

    /// The existing folder `root`, which `lock` holds (taken earlier, with
    /// [`FolderLock::take`], by a command that checks its inputs before it
    /// writes): the temporary files killed runs left are removed and its
    /// record opened.
    pub fn with_lock(root: &Path, lock: FolderLock) -> Result<Self> {
        lock.announce()?;
        let removed_partials = crate::atomic::remove_stale_partials(root)?;
        let written = Written::read(root)?;
        let path = root.join(RECORD_FILE);
        let record = open_own(&path, fs::OpenOptions::new().append(true).create(true))?;
        Ok(Self {
            written,
            record: Mutex::new((record, HashSet::new())),
            removed_partials,
            _lock: lock,
        })
    }

    /// How many temporary files of killed runs [`OutDir::take`] removed.
    pub fn removed_partials(&self) -> usize {
        self.removed_partials
    }

    /// What the record listed when the folder was taken.
    pub fn written(&self) -> &Written {
        &self.written
    }

    /// Refuses an `output` that exists and that mbs did not write
    /// ([`Written::refuse_foreign`]).
    pub fn refuse_foreign(&self, output: &Path) -> Result<()> {
        self.written.refuse_foreign(output)
    }

    /// Adds `outputs` (paths inside the folder; a name ending in `/` for a
    /// whole folder) to the record, before they are written.
    pub fn record<P: AsRef<Path>>(&self, outputs: impl IntoIterator<Item = P>) -> Result<()> {
        let path = self.written.root.join(RECORD_FILE);
        let mut record = self
            .record
            .lock()
            .map_err(|_| FormatError::invalid(&path, "a writer of the record panicked"))?;
        let (file, added) = &mut *record;
        let mut text = String::new();
        for output in outputs {
            let output = output.as_ref();
            let Some(mut name) = name_in(&self.written.root, output) else {
                continue;
            };
            if output.as_os_str().to_string_lossy().ends_with('/') {
                name.push('/');
            }
            if !self.written.names.contains(&name) && added.insert(name.clone()) {
                text.push_str(&name);
                text.push('\n');
            }
        }
        file.write_all(text.as_bytes())
            .map_err(|e| FormatError::io(&path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_recorded_outputs_may_be_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("out");
        let out = OutDir::take(&root, Share::Whole, "test").unwrap();
        let ours = root.join("a/000000_10.png");
        let theirs = root.join("b/000000_10.png");
        let run = root.join("checkpoints/step-1/teacher.bpk");
        for path in [&ours, &theirs, &run] {
            fs::create_dir_all(path.parent().unwrap()).unwrap();
            fs::write(path, b"x").unwrap();
        }
        out.record([&ours, &root.join("checkpoints/")]).unwrap();
        out.record([&ours]).unwrap();
        drop(out);
        let text = fs::read_to_string(root.join(RECORD_FILE)).unwrap();
        assert_eq!(text, "a/000000_10.png\ncheckpoints/\n");
        let out = OutDir::take(&root, Share::Whole, "test").unwrap();
        assert!(out.refuse_foreign(&ours).is_ok());
        assert!(out.refuse_foreign(&run).is_ok());
        assert!(out.refuse_foreign(&root.join("checkpoints/")).is_ok());
        assert!(out.refuse_foreign(&root.join("checkpoints")).is_ok());
        assert!(out.refuse_foreign(&root.join("c.png")).is_ok());
        let err = out.refuse_foreign(&theirs).unwrap_err().to_string();
        assert!(
            err.contains("b/000000_10.png: exists, and mbs did not write it"),
            "{err}"
        );
        assert_eq!(fs::read(&theirs).unwrap(), b"x");
    }

    #[test]
    fn a_new_folder_that_appeared_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("run");
        let first = OutDir::take_new(&root, Share::Whole, "train").unwrap();
        let err = OutDir::take_new(&root, Share::Whole, "train")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("appeared while this command was starting"),
            "{err}"
        );
        drop(first);
    }
}
