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
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::confine::name_inside;
use crate::error::{FormatError, Result};
use crate::lock::{FolderLock, Share, files_of_every_share, open_own};

/// The record of the files mbs wrote in an output folder; each shard of a
/// `--shard K/N` job keeps its own beside it (`.mbs-written.shard-K-of-N`),
/// so that no two processes append to one file, and the folder's record
/// is the union of them all.
pub const RECORD_FILE: &str = ".mbs-written";

/// The names an output folder's records list.
#[derive(Debug, Default)]
pub struct Written {
    /// The folder.
    root: PathBuf,
    /// Its records' names.
    names: HashSet<String>,
}

impl Written {
    /// The records of `root`, read without writing anything: empty when
    /// the folder or its records are absent. A last line without its end
    /// (a record being written) is left out.
    pub fn read(root: &Path) -> Result<Self> {
        let mut names = HashSet::new();
        for record in files_of_every_share(root, RECORD_FILE) {
            let mut text = String::new();
            open_own(&record, fs::OpenOptions::new().read(true))?
                .read_to_string(&mut text)
                .map_err(|e| FormatError::io(&record, e))?;
            let complete = text.rfind('\n').map_or("", |end| &text[..end]);
            names.extend(complete.lines().map(str::to_string));
        }
        Ok(Self {
            root: root.to_path_buf(),
            names,
        })
    }

    /// Whether the records list nothing (a new folder, or one that an mbs
    /// older than the record wrote).
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Whether the records list `path` (a file or folder inside the
    /// folder), by name or under a listed folder.
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
    /// nothing) and that the records do not list.
    pub fn refuse_foreign(&self, output: &Path) -> Result<()> {
        if fs::symlink_metadata(output).is_err() || self.lists(output) {
            return Ok(());
        }
        Err(FormatError::invalid(
            output,
            format!(
                "exists, and mbs did not write it ({} does not list it): it may be a \
                 dataset's or your own file, or an output of an mbs older than that \
                 record, so it is neither replaced nor taken as a finished output, \
                 whatever the flags; move it away or choose another output folder",
                self.root.join(RECORD_FILE).display()
            ),
        ))
    }
}

/// `path`'s confined name inside `root` ([`crate::confine::name_inside`]);
/// `None` outside it, or when the name breaks the rule (a control
/// character could not be told apart from the record's line breaks).
fn name_in(root: &Path, path: &Path) -> Option<String> {
    let here = root.as_os_str().is_empty() || root == Path::new(".");
    match here && path.is_relative() {
        true => name_inside(Path::new(""), path.strip_prefix(".").unwrap_or(path)),
        false => name_inside(root, path),
    }
}

/// An output folder held by this process.
#[derive(Debug)]
pub struct OutDir {
    /// What its records listed when it was taken.
    written: Written,
    /// This process's record, open for appending, and the names it added.
    record: Mutex<(fs::File, HashSet<String>)>,
    /// The path of that record.
    record_path: PathBuf,
    /// Whether this process holds the whole folder (not one shard).
    whole: bool,
    /// The folder's lock, held as long as this lives.
    lock: FolderLock,
}

impl OutDir {
    /// Makes `root` (and its parents; a file in its place is refused),
    /// takes its lock for `share` as `holder` (e.g. "mbs-tool predict")
    /// and opens its record.
    pub fn take(root: &Path, share: Share, holder: &str) -> Result<Self> {
        crate::confine::create_out_dir(root)?;
        let lock = FolderLock::take(root, share, holder)?;
        Self::with_lock(root, share, lock)
    }

    /// Makes the folder `root`, which must not exist yet (its parents are
    /// made), and takes it for `share`: refused when it appeared since the
    /// caller saw it absent (naming its holder when one holds it).
    pub fn take_new(root: &Path, share: Share, holder: &str) -> Result<Self> {
        if let Some(parent) = root.parent().filter(|p| !p.as_os_str().is_empty()) {
            fs::create_dir_all(parent).map_err(|e| FormatError::io(parent, e))?;
        }
        if let Err(e) = fs::create_dir(root) {
            if e.kind() != std::io::ErrorKind::AlreadyExists {
                return Err(FormatError::io(root, e));
            }
            // Taking it names the process that made it, if it holds it.
            drop(FolderLock::take(root, share, holder)?);
            return Err(FormatError::invalid(
                root,
                "appeared while this command was starting (another process?); \
                 run it again to resume there, or choose another output folder",
            ));
        }
        let lock = FolderLock::take(root, share, holder)?;
        Self::with_lock(root, share, lock)
    }

    /// The existing folder `root`, which `lock` holds for `share` (taken
    /// earlier with [`FolderLock::take`] by a command that checks its
    /// outputs in between), its records read and this process's opened.
    pub fn with_lock(root: &Path, share: Share, lock: FolderLock) -> Result<Self> {
        let written = Written::read(root)?;
        let record_path = root.join(share.file_name(RECORD_FILE));
        let record = open_own(
            &record_path,
            fs::OpenOptions::new().append(true).create(true),
        )?;
        Ok(Self {
            written,
            record: Mutex::new((record, HashSet::new())),
            record_path,
            whole: share == Share::Whole,
            lock,
        })
    }

    /// Removes the temporary files that killed runs left in the folder, once
    /// the command's checks have passed; returns how many. Only a process
    /// that holds the whole folder does: a shard's partner on another
    /// machine may still be writing its own.
    pub fn remove_stale_partials(&self) -> Result<usize> {
        match self.whole {
            true => crate::atomic::remove_stale_partials(&self.written.root),
            false => Ok(0),
        }
    }

    /// A warning for the user when the folder could not be locked.
    pub fn lock_warning(&self) -> Option<String> {
        self.lock.warning(&self.written.root)
    }

    /// What the records listed when the folder was taken.
    pub fn written(&self) -> &Written {
        &self.written
    }

    /// Adds `outputs` (paths inside the folder; a name ending in `/` for a
    /// whole folder) to this process's record, before they are written. An
    /// output outside the folder, or whose name breaks the confined-name
    /// rule, cannot be recorded: an error naming it.
    pub fn record<P: AsRef<Path>>(&self, outputs: impl IntoIterator<Item = P>) -> Result<()> {
        let path = &self.record_path;
        let mut record = self
            .record
            .lock()
            .map_err(|_| FormatError::invalid(path, "a writer of the record panicked"))?;
        let (file, added) = &mut *record;
        let mut text = String::new();
        for output in outputs {
            let output = output.as_ref();
            let mut name = name_in(&self.written.root, output).ok_or_else(|| {
                FormatError::invalid(
                    output,
                    format!(
                        "cannot be recorded in {}: it is not inside that folder, or its \
                         name holds a control character, a backslash or a colon",
                        path.display()
                    ),
                )
            })?;
            if output.as_os_str().to_string_lossy().ends_with('/') {
                name.push('/');
            }
            if !self.written.names.contains(&name) && added.insert(name.clone()) {
                text.push_str(&name);
                text.push('\n');
            }
        }
        file.write_all(text.as_bytes())
            .map_err(|e| FormatError::io(path, e))
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
        assert!(out.written().refuse_foreign(&ours).is_ok());
        assert!(out.written().refuse_foreign(&run).is_ok());
        assert!(
            out.written()
                .refuse_foreign(&root.join("checkpoints/"))
                .is_ok()
        );
        assert!(
            out.written()
                .refuse_foreign(&root.join("checkpoints"))
                .is_ok()
        );
        assert!(out.written().refuse_foreign(&root.join("c.png")).is_ok());
        let err = out
            .written()
            .refuse_foreign(&theirs)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("b/000000_10.png: exists, and mbs did not write it"),
            "{err}"
        );
        assert_eq!(fs::read(&theirs).unwrap(), b"x");
    }

    #[test]
    fn a_new_folder_that_appeared_is_refused_naming_its_holder() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("run");
        let first = OutDir::take_new(&root, Share::Whole, "mbs-tool train").unwrap();
        let err = OutDir::take_new(&root, Share::Whole, "mbs-tool train")
            .unwrap_err()
            .to_string();
        assert!(err.contains("is in use by process"), "{err}");
        drop(first);
        let err = OutDir::take_new(&root, Share::Whole, "mbs-tool train")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("appeared while this command was starting"),
            "{err}"
        );
    }

    /// Shards record apart and every record counts; a name with a line
    /// break cannot be recorded, and an unfinished last line is not read.
    #[test]
    fn shards_record_apart_and_odd_names_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("out");
        let shard = |index| Share::Shard { index, count: 2 };
        let zero = OutDir::take(&root, shard(0), "predict").unwrap();
        let one = OutDir::take(&root, shard(1), "predict").unwrap();
        zero.record([root.join("a.pfm")]).unwrap();
        one.record([root.join("b.pfm")]).unwrap();
        let err = one.record([root.join("x\ntrainingQ/")]).unwrap_err();
        assert!(err.to_string().contains("cannot be recorded"), "{err}");
        let err = one.record([dir.path().join("elsewhere.pfm")]).unwrap_err();
        assert!(err.to_string().contains("not inside that folder"), "{err}");
        drop((zero, one));
        let shard_record = root.join(format!("{RECORD_FILE}.shard-1-of-2"));
        assert_eq!(fs::read_to_string(&shard_record).unwrap(), "b.pfm\n");
        std::io::Write::write_all(
            &mut fs::OpenOptions::new()
                .append(true)
                .open(&shard_record)
                .unwrap(),
            b"half",
        )
        .unwrap();
        let written = Written::read(&root).unwrap();
        for name in ["a.pfm", "b.pfm"] {
            fs::write(root.join(name), b"x").unwrap();
            assert!(written.refuse_foreign(&root.join(name)).is_ok());
        }
        fs::write(root.join("half"), b"x").unwrap();
        assert!(written.refuse_foreign(&root.join("half")).is_err());
    }
}
