//! One process at a time in an output folder: a kernel lock (`flock`) on a
//! file in the folder, which the kernel releases when the process ends, a
//! `kill -9` included, so a stale lock never needs cleaning.
//!
//! A whole job takes [`LOCK_FILE`] alone. The shards of a job split over
//! processes (`--shard K/N`, whose outputs never overlap) share it and take
//! one file of their own each (`.mbs-lock.shard-K-of-N`), so a second
//! process for the same shard, or a whole job beside the shards, is
//! refused. The holder writes who it is (process, host, command, time)
//! into the file it holds alone, and a refused process names it.

use std::fs;
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

use crate::error::{FormatError, Result};

/// The lock file of an output folder.
pub const LOCK_FILE: &str = ".mbs-lock";

/// Which part of the work in a folder a process holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Share {
    /// All of it: no other process may write there.
    Whole,
    /// Shard `index` of `count` of a job whose shards write apart.
    Shard {
        /// The shard, 0-based.
        index: usize,
        /// The number of shards.
        count: usize,
    },
}

impl Share {
    /// The name of this share's own file of the kind `base` (the lock, the
    /// record): `base` for a whole job, `base.shard-K-of-N` for a shard.
    pub fn file_name(self, base: &str) -> String {
        match self {
            Share::Whole => base.to_string(),
            Share::Shard { index, count } => format!("{base}.shard-{index}-of-{count}"),
        }
    }
}

/// Every share's file of the kind `base` in `dir` (`base` and its shards'
/// `base.shard-K-of-N`), sorted; none when `dir` cannot be listed.
pub(crate) fn files_of_every_share(dir: &Path, base: &str) -> Vec<PathBuf> {
    let Ok(entries) = fs::read_dir(dir) else {
        return Vec::new();
    };
    let shards = format!("{base}.shard-");
    let mut found: Vec<PathBuf> = entries
        .flatten()
        .map(|entry| entry.path())
        .filter(|path| {
            path.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n == base || n.starts_with(&shards))
        })
        .collect();
    found.sort();
    found
}

/// A held lock on an output folder; dropping it (or the process ending)
/// releases it.
#[derive(Debug)]
pub struct FolderLock {
    /// The files held, kept open for as long as the lock lasts.
    _held: Vec<fs::File>,
    /// Whether the file system refused locks altogether (see
    /// [`FolderLock::warning`]).
    unsupported: bool,
}

impl FolderLock {
    /// Locks the existing folder `dir` for `share`, as `holder` (e.g.
    /// "mbs-tool train"), and writes who holds it in the lock file it
    /// holds alone; a folder another process holds is refused at once,
    /// naming that process. On a file system without locks (Lustre
    /// mounted without `flock`, some FUSE mounts) the folder is taken
    /// unlocked, which [`FolderLock::warning`] says.
    pub fn take(dir: &Path, share: Share, holder: &str) -> Result<Self> {
        let main = dir.join(LOCK_FILE);
        let main_file = open_lock_file(&main)?;
        let (held, supported) = match share {
            Share::Whole => {
                let supported = lock(&main_file, dir, Mode::Exclusive)?;
                write_holder(&main_file, &main, holder)?;
                (vec![main_file], supported)
            }
            Share::Shard { index, count } => {
                let supported = lock(&main_file, dir, Mode::Shared)?;
                let own = dir.join(share.file_name(LOCK_FILE));
                let own_file = open_lock_file(&own)?;
                lock(&own_file, dir, Mode::Exclusive)?;
                write_holder(&own_file, &own, &format!("{holder}, shard {index}/{count}"))?;
                (vec![main_file, own_file], supported)
            }
        };
        Ok(Self {
            _held: held,
            unsupported: !supported,
        })
    }

    /// A warning for the user when the folder could not be locked (its
    /// file system has no locks), naming `dir`.
    pub fn warning(&self, dir: &Path) -> Option<String> {
        self.unsupported.then(|| {
            format!(
                "{}: this file system does not support locks (flock), so nothing stops \
                 another process from writing this folder at the same time",
                dir.display()
            )
        })
    }
}

/// How a lock is taken.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// Alone.
    Exclusive,
    /// Beside other shards.
    Shared,
}

/// Opens (making it when missing) the lock file `path` for reading and
/// writing ([`open_own`]).
fn open_lock_file(path: &Path) -> Result<fs::File> {
    open_own(
        path,
        fs::OpenOptions::new().read(true).write(true).create(true),
    )
}

/// Opens a file mbs keeps in an output folder (a lock, a record) with
/// `options`, never through a symbolic link and never blocking: anything
/// but a regular file at `path` is refused, naming what it is.
pub(crate) fn open_own(path: &Path, options: &mut fs::OpenOptions) -> Result<fs::File> {
    #[cfg(unix)]
    {
        use rustix::fs::OFlags;
        use std::os::unix::fs::OpenOptionsExt;
        let flags = OFlags::NONBLOCK | OFlags::NOFOLLOW | OFlags::CLOEXEC;
        options.custom_flags(flags.bits() as i32).mode(0o644);
    }
    let refusal = |kind: &fs::FileType| match kind.is_symlink() {
        true => FormatError::invalid(
            path,
            "is a symbolic link; mbs never writes its own files through a link (remove it)",
        ),
        false => FormatError::invalid(
            path,
            format!(
                "is {}, not a regular file (remove it)",
                crate::regular::describe(kind)
            ),
        ),
    };
    let file = options
        .open(path)
        .map_err(|e| match fs::symlink_metadata(path) {
            Ok(m) if !m.is_file() => refusal(&m.file_type()),
            _ => FormatError::io(path, e),
        })?;
    let metadata = file.metadata().map_err(|e| FormatError::io(path, e))?;
    match metadata.is_file() {
        true => Ok(file),
        false => Err(refusal(&metadata.file_type())),
    }
}

/// Takes `file`'s lock in `mode` without waiting: `true` when taken,
/// `false` when the file system has no locks; a lock held elsewhere is an
/// error about `dir` that names its holders.
#[cfg(unix)]
fn lock(file: &fs::File, dir: &Path, mode: Mode) -> Result<bool> {
    use rustix::fs::{FlockOperation, flock};
    use rustix::io::Errno;
    let operation = match mode {
        Mode::Exclusive => FlockOperation::NonBlockingLockExclusive,
        Mode::Shared => FlockOperation::NonBlockingLockShared,
    };
    match flock(file, operation) {
        Ok(()) => Ok(true),
        Err(Errno::WOULDBLOCK) => Err(FormatError::invalid(
            dir,
            format!(
                "is in use by {}; one process writes an output folder at a time: \
                 wait for it to end, or choose another output folder",
                holders(dir)
            ),
        )),
        Err(Errno::NOSYS | Errno::OPNOTSUPP | Errno::NOLCK) => Ok(false),
        Err(e) => Err(FormatError::io(&dir.join(LOCK_FILE), e.into())),
    }
}

/// Without `flock`, folders are not locked.
#[cfg(not(unix))]
fn lock(_: &fs::File, _: &Path, _: Mode) -> Result<bool> {
    Ok(false)
}

/// Seconds since the Unix epoch, now.
fn now_seconds() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

/// This machine's name, as the holders' lines give it ("" when unknown).
fn hostname() -> String {
    fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .unwrap_or_default()
}

/// Replaces the content of the held lock file `file` with who holds it:
/// a line naming the process, then `since=SECONDS` (from the Unix epoch).
fn write_holder(mut file: &fs::File, path: &Path, holder: &str) -> Result<()> {
    let text = format!(
        "process {} ({holder}) on {}\nsince={}\n",
        std::process::id(),
        hostname(),
        now_seconds()
    );
    file.set_len(0)
        .and_then(|()| file.rewind())
        .and_then(|()| file.write_all(text.as_bytes()))
        .map_err(|e| FormatError::io(path, e))
}

/// A holder's lock file `text` in words: who, and for how long.
fn describe_holder(text: &str) -> Option<String> {
    let mut lines = text.lines();
    let who = lines.next().filter(|w| !w.trim().is_empty())?.trim();
    if !may_be_running(who) {
        return None;
    }
    let since = lines
        .find_map(|line| line.strip_prefix("since="))
        .and_then(|s| s.trim().parse::<u64>().ok());
    Some(match since {
        Some(since) => format!("{who}, for {} s", now_seconds().saturating_sub(since)),
        None => who.to_string(),
    })
}

/// Whether the process a holder's line `who` names ("process PID (...) on
/// HOST") may still run: one of this machine that has ended left a line
/// behind it (a holder that has not written its own yet, or a shared lock).
fn may_be_running(who: &str) -> bool {
    let pid = who
        .strip_prefix("process ")
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|pid| pid.parse().ok());
    let this_host = who.ends_with(&format!(" on {}", hostname()));
    match pid {
        Some(pid) if this_host => crate::atomic::is_running(pid),
        _ => true,
    }
}

/// Who holds `dir`'s locks, in words, from the lock files of the holders
/// still holding them.
fn holders(dir: &Path) -> String {
    let mut found: Vec<String> = files_of_every_share(dir, LOCK_FILE)
        .iter()
        .filter(|path| is_held(path))
        .filter_map(|path| {
            let mut text = String::new();
            open_lock_file(path).ok()?.read_to_string(&mut text).ok()?;
            describe_holder(&text)
        })
        .collect();
    found.sort();
    match found.is_empty() {
        true => "another process".into(),
        false => found.join("; "),
    }
}

/// Whether some process holds `path`'s lock (exclusively or shared).
#[cfg(unix)]
fn is_held(path: &Path) -> bool {
    use rustix::fs::{FlockOperation, flock};
    let Ok(file) = open_lock_file(path) else {
        return false;
    };
    match flock(&file, FlockOperation::NonBlockingLockExclusive) {
        Ok(()) => {
            let _ = flock(&file, FlockOperation::Unlock);
            false
        }
        Err(_) => true,
    }
}

#[cfg(not(unix))]
fn is_held(_: &Path) -> bool {
    false
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn a_held_folder_is_refused_naming_its_holder_and_released_on_drop() {
        let dir = tempfile::tempdir().unwrap();
        let first = FolderLock::take(dir.path(), Share::Whole, "mbs-tool train").unwrap();
        let err = FolderLock::take(dir.path(), Share::Whole, "mbs-tool train")
            .unwrap_err()
            .to_string();
        let pid = std::process::id().to_string();
        assert!(err.contains("is in use by process"), "{err}");
        assert!(
            err.contains(&pid) && err.contains("mbs-tool train"),
            "{err}"
        );
        drop(first);
        FolderLock::take(dir.path(), Share::Whole, "mbs-tool train").unwrap();
    }

    #[test]
    fn shards_share_a_folder_but_not_a_shard_nor_with_a_whole_job() {
        let dir = tempfile::tempdir().unwrap();
        let shard = |index| Share::Shard { index, count: 2 };
        let zero = FolderLock::take(dir.path(), shard(0), "predict").unwrap();
        let one = FolderLock::take(dir.path(), shard(1), "predict").unwrap();
        let err = FolderLock::take(dir.path(), shard(1), "predict")
            .unwrap_err()
            .to_string();
        assert!(err.contains("shard 1/2"), "{err}");
        let err = FolderLock::take(dir.path(), Share::Whole, "predict")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("shard 0/2") && err.contains("shard 1/2"),
            "{err}"
        );
        drop((zero, one));
        FolderLock::take(dir.path(), Share::Whole, "predict").unwrap();
    }

    #[test]
    fn a_link_or_a_fifo_as_the_lock_file_is_refused_and_left_alone() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("precious.txt");
        fs::write(&target, "mine").unwrap();
        std::os::unix::fs::symlink(&target, dir.path().join(LOCK_FILE)).unwrap();
        let err = FolderLock::take(dir.path(), Share::Whole, "x")
            .unwrap_err()
            .to_string();
        assert!(err.contains("symbolic link"), "{err}");
        assert_eq!(fs::read_to_string(&target).unwrap(), "mine");
        let other = tempfile::tempdir().unwrap();
        let status = std::process::Command::new("mkfifo")
            .arg(other.path().join(LOCK_FILE))
            .status();
        assert!(status.is_ok_and(|s| s.success()), "mkfifo");
        let err = FolderLock::take(other.path(), Share::Whole, "x")
            .unwrap_err()
            .to_string();
        assert!(err.contains("FIFO"), "{err}");
    }
}
