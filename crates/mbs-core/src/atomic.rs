//! Crash-safe file writing: write to a temporary name beside the target, then
//! rename. A killed process (crash, Ctrl-C, `kill -9`) leaves at most a
//! `*.partial` file, never a truncated file under the final name that a
//! re-run would trust. Temporary names are unique per process and write, so
//! two processes writing the same output never trip over each other: the
//! last rename wins, and both wrote the same content. Files are not
//! fsync'ed: that would guard against a power cut too, at several
//! milliseconds per file.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{FormatError, Result};

/// Suffix of in-progress files and folders.
pub const PARTIAL_SUFFIX: &str = ".partial";

/// The longest file name, in bytes, of the file systems mbs writes to.
const MAX_FILE_NAME: usize = 255;

/// A temporary name for `path`, unique to this process and call:
/// `NAME.PID-N.partial`, with `NAME` shortened (at a character boundary)
/// where the whole would pass the file systems' 255 bytes, so that any
/// name a file system takes can be written.
pub fn partial_path(path: &Path) -> PathBuf {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    let tag = format!(".{}-{n}{PARTIAL_SUFFIX}", std::process::id());
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let mut keep = name.len().min(MAX_FILE_NAME - tag.len());
    while !name.is_char_boundary(keep) {
        keep -= 1;
    }
    path.with_file_name(format!("{}{tag}", &name[..keep]))
}

/// The process id a temporary name was made by, if `name` is one.
fn partial_owner(name: &str) -> Option<u32> {
    let stem = name.strip_suffix(PARTIAL_SUFFIX)?;
    let (_, tag) = stem.rsplit_once('.')?;
    tag.split_once('-')?.0.parse().ok()
}

/// Whether process `pid` still runs. Without `/proc` (not Linux) every
/// process is assumed alive, so nothing is removed.
pub(crate) fn is_running(pid: u32) -> bool {
    let proc_root = Path::new("/proc");
    !proc_root.is_dir() || proc_root.join(pid.to_string()).exists()
}

/// Removes the temporary files and folders that killed processes left
/// anywhere under `dir` (those of running processes are kept); returns how
/// many were removed. A missing `dir` has none.
pub fn remove_stale_partials(dir: &Path) -> Result<usize> {
    let Ok(entries) = fs::read_dir(dir) else {
        return Ok(0);
    };
    let mut removed = 0;
    for entry in entries {
        let entry = entry.map_err(|e| FormatError::io(dir, e))?;
        let path = entry.path();
        let file_type = entry.file_type().map_err(|e| FormatError::io(&path, e))?;
        let stale = entry
            .file_name()
            .to_str()
            .and_then(partial_owner)
            .is_some_and(|pid| !is_running(pid));
        if stale {
            let result = if file_type.is_dir() {
                fs::remove_dir_all(&path)
            } else {
                fs::remove_file(&path)
            };
            result.map_err(|e| FormatError::io(&path, e))?;
            removed += 1;
        } else if file_type.is_dir() {
            removed += remove_stale_partials(&path)?;
        }
    }
    Ok(removed)
}

/// Writes `path` atomically: `write` fills a buffered writer on a temporary
/// file, which is flushed and renamed to `path` only on success.
/// Parent folders are created as needed.
pub fn write_atomic<F>(path: &Path, write: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<fs::File>) -> std::io::Result<()>,
{
    place_atomically(path, |partial| {
        let file = fs::File::create(partial)?;
        let mut writer = BufWriter::with_capacity(1 << 20, file);
        write(&mut writer)?;
        writer.flush()
    })
}

/// Refuses a `path` that exists and is not a regular file (a device, FIFO,
/// socket or folder, also behind a symbolic link), which a rename would
/// replace: writing a PNG to `/dev/null` must not turn the device into a
/// file. A missing `path`, or a link to nothing, is fine.
pub fn refuse_special_target(path: &Path) -> Result<()> {
    let Ok(metadata) = fs::metadata(path) else {
        return Ok(());
    };
    let kind = metadata.file_type();
    if kind.is_file() {
        return Ok(());
    }
    Err(FormatError::invalid(
        path,
        format!(
            "exists and is {}, not a regular file; refusing to replace it (give a file name)",
            crate::regular::describe(&kind)
        ),
    ))
}

/// Creates `path`'s folders, lets `fill` make the file at a fresh temporary
/// name and renames it to `path`; on failure the temporary is removed. A
/// `path` that is not a regular file is refused before anything is made.
fn place_atomically(path: &Path, fill: impl FnOnce(&Path) -> std::io::Result<()>) -> Result<()> {
    refuse_special_target(path)?;
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        fs::create_dir_all(parent).map_err(|e| FormatError::io(parent, e))?;
    }
    let partial = partial_path(path);
    fill(&partial).map_err(|e| {
        // Best effort: the partial file is garbage either way.
        let _ = fs::remove_file(&partial);
        FormatError::io(path, e)
    })?;
    publish(&partial, path)
}

/// Renames the finished `partial` to `path` without ever replacing a file
/// that is not a regular file, even one made at `path` while `partial` was
/// written (a check before a plain rename would leave that moment open).
///
/// On Linux: `renameat2` with `RENAME_NOREPLACE` when `path` is absent
/// (the kernel refuses if something appeared); when something is there,
/// `RENAME_EXCHANGE` swaps the two atomically and what came out is looked
/// at under the temporary name: a regular file (or a link to one, or to
/// nothing) is removed, anything else is swapped back and refused. A file
/// system without these flags gets the check and a plain rename. On
/// failure the temporary file is removed, unless it holds the user's file
/// (a swap back that failed, which the error says).
fn publish(partial: &Path, path: &Path) -> Result<()> {
    let result = publish_exclusively(partial, path).unwrap_or_else(|| {
        refuse_special_target(path)
            .and_then(|()| fs::rename(partial, path).map_err(|e| FormatError::io(path, e)))
            .map_err(Unpublished::Ours)
    });
    result.map_err(|unpublished| match unpublished {
        Unpublished::Ours(e) => {
            let _ = fs::remove_file(partial);
            e
        }
        Unpublished::Theirs(e) => e,
    })
}

/// Why a finished file was not published, by who owns what is left at its
/// temporary name.
enum Unpublished {
    /// The temporary name holds the command's file: it is removed.
    Ours(FormatError),
    /// It holds the user's file, which a swap back failed to return: it is
    /// left there, and the error says where.
    Theirs(FormatError),
}

/// [`publish`] through `renameat2`; `None` where the file system or the
/// kernel does not offer it.
#[cfg(target_os = "linux")]
fn publish_exclusively(
    partial: &Path,
    path: &Path,
) -> Option<std::result::Result<(), Unpublished>> {
    use rustix::fs::{CWD, RenameFlags, renameat_with};
    use rustix::io::Errno;
    let unsupported = |e: Errno| e == Errno::INVAL || e == Errno::NOSYS || e == Errno::NOTSUP;
    let failed = |e: Errno| Some(Err(Unpublished::Ours(FormatError::io(path, e.into()))));
    loop {
        match renameat_with(CWD, partial, CWD, path, RenameFlags::NOREPLACE) {
            Ok(()) => return Some(Ok(())),
            Err(e) if unsupported(e) => return None,
            Err(e) if e != Errno::EXIST => return failed(e),
            Err(_) => {}
        }
        match renameat_with(CWD, partial, CWD, path, RenameFlags::EXCHANGE) {
            Ok(()) => return Some(take_out_replaced(partial, path)),
            // Removed between the two calls: try the first again.
            Err(Errno::NOENT) => {}
            Err(e) if unsupported(e) => return None,
            Err(e) => return failed(e),
        }
    }
}

/// After the exchange, `partial` holds what was at `path`: removed when
/// it is a regular file (or a link to one, or to nothing: best effort, the
/// output is in place either way); otherwise the two are swapped back and
/// the write refused.
#[cfg(target_os = "linux")]
fn take_out_replaced(partial: &Path, path: &Path) -> std::result::Result<(), Unpublished> {
    use rustix::fs::{CWD, RenameFlags, renameat_with};
    match fs::metadata(partial) {
        Ok(metadata) if !metadata.is_file() => {
            let kind = crate::regular::describe(&metadata.file_type());
            if let Err(e) = renameat_with(CWD, partial, CWD, path, RenameFlags::EXCHANGE) {
                return Err(Unpublished::Theirs(FormatError::invalid(
                    path,
                    format!(
                        "was {kind}, which appeared while the output was written; swapping it \
                         back failed ({e}), so it is now at {}: move it back",
                        partial.display()
                    ),
                )));
            }
            Err(Unpublished::Ours(FormatError::invalid(
                path,
                format!(
                    "is {kind}, not a regular file (it appeared while the output was written); \
                     refusing to replace it"
                ),
            )))
        }
        _ => {
            let _ = fs::remove_file(partial);
            Ok(())
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn publish_exclusively(_: &Path, _: &Path) -> Option<std::result::Result<(), Unpublished>> {
    None
}

/// Places a copy of `source` at `path` atomically: a hard link where the
/// file system allows it (no space used), else a copy. Nothing is done when
/// `path` already is `source`.
pub fn link_or_copy(source: &Path, path: &Path) -> Result<()> {
    if crate::inputs::same_file(source, path) {
        return Ok(());
    }
    if !source.is_file() {
        return Err(FormatError::invalid(source, "missing, or not a file"));
    }
    place_atomically(path, |partial| match fs::hard_link(source, partial) {
        // A FIFO swapped in after the check is linked, not read: refused.
        Ok(()) if fs::symlink_metadata(partial)?.is_file() => Ok(()),
        Ok(()) => Err(std::io::Error::other(format!(
            "{} is no longer a regular file",
            source.display()
        ))),
        Err(_) => {
            let mut from = crate::regular::open_regular(source).map_err(std::io::Error::other)?;
            std::io::copy(&mut from, &mut fs::File::create(partial)?).map(|_| ())
        }
    })
}

/// Writes `bytes` to `path` atomically.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_and_leaves_no_partial_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/out.bin");
        write_bytes_atomic(&path, b"hello").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"hello");
        assert!(!partial_path(&path).exists());
    }

    #[test]
    fn failed_write_keeps_previous_content() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        write_bytes_atomic(&path, b"old").unwrap();
        let err = write_atomic(&path, |w| {
            w.write_all(b"new but broken")?;
            Err(std::io::Error::other("disk on fire"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("out.bin"), "{err}");
        assert!(err.to_string().contains("disk on fire"), "{err}");
        assert_eq!(fs::read(&path).unwrap(), b"old");
        assert!(!partial_path(&path).exists());
    }

    /// A device, a FIFO, a socket or a folder under the target's name (or
    /// behind a link of that name) is refused, named, and left as it was;
    /// nothing is left in its folder.
    #[cfg(unix)]
    #[test]
    fn a_target_that_is_not_a_regular_file_is_refused_and_untouched() {
        use mbs_test_support::special::{identity, special_files};
        let dir = tempfile::tempdir().unwrap();
        let source = dir.path().join("source.bin");
        fs::write(&source, b"pixels").unwrap();
        let special = special_files(dir.path(), "png");
        let link = dir.path().join("link.png");
        std::os::unix::fs::symlink(&special[0].path, &link).unwrap();
        let targets = special
            .iter()
            .map(|file| (file.path.clone(), file.kind))
            .chain([(link.clone(), special[0].kind)]);
        for (target, kind) in targets {
            let before = (
                identity(&target),
                fs::symlink_metadata(&link).unwrap().file_type(),
            );
            let err = write_bytes_atomic(&target, b"png").unwrap_err().to_string();
            assert!(err.contains(&target.display().to_string()), "{err}");
            assert!(
                err.contains(kind) && err.contains("not a regular file"),
                "{err}"
            );
            let err = link_or_copy(&source, &target).unwrap_err().to_string();
            assert!(err.contains("not a regular file"), "{err}");
            let after = (
                identity(&target),
                fs::symlink_metadata(&link).unwrap().file_type(),
            );
            assert_eq!(before, after, "{}", target.display());
        }
        assert!(fs::read_dir(&special[3].path).unwrap().next().is_none());
        let names: Vec<String> = fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|name| name.ends_with(PARTIAL_SUFFIX))
            .collect();
        assert!(names.is_empty(), "{names:?}");
        // A link to nothing is replaced as a missing file would be.
        let dangling = dir.path().join("dangling.png");
        std::os::unix::fs::symlink(dir.path().join("gone"), &dangling).unwrap();
        write_bytes_atomic(&dangling, b"png").unwrap();
        assert_eq!(fs::read(&dangling).unwrap(), b"png");
    }

    /// A FIFO made at the target after the check, while the temporary file
    /// was written, is swapped back and refused: the rename never replaces
    /// it (it used to, about 1 try in 10 with a racing process).
    #[cfg(target_os = "linux")]
    #[test]
    fn a_special_file_that_appears_before_the_rename_is_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.pfm");
        let partial = partial_path(&path);
        fs::write(&partial, b"finished").unwrap();
        let made = std::process::Command::new("mkfifo").arg(&path).status();
        assert!(made.unwrap().success());
        let err = publish(&partial, &path).unwrap_err().to_string();
        assert!(err.contains("FIFO") && err.contains("appeared"), "{err}");
        assert!(fs::symlink_metadata(&path).unwrap().file_type().is_fifo());
        assert!(!partial.exists(), "the refused output is left behind");
        // A regular file there is replaced, and nothing is left behind.
        fs::remove_file(&path).unwrap();
        fs::write(&path, b"old").unwrap();
        fs::write(&partial, b"finished").unwrap();
        publish(&partial, &path).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"finished");
        assert!(!partial.exists());
    }

    /// A name of 250 characters is legal (255 bytes is the limit); its
    /// temporary name used to pass the limit and fail.
    #[test]
    fn the_longest_legal_names_can_be_written() {
        let dir = tempfile::tempdir().unwrap();
        for length in [249, 250, 255] {
            let path = dir.path().join("d".repeat(length));
            write_bytes_atomic(&path, b"x").unwrap();
            assert_eq!(fs::read(&path).unwrap(), b"x");
        }
        let accented = dir.path().join("é".repeat(127));
        write_bytes_atomic(&accented, b"y").unwrap();
        assert!(partial_path(&accented).file_name().unwrap().len() <= 255);
    }

    #[test]
    fn link_or_copy_places_the_same_bytes_once() {
        let dir = tempfile::tempdir().unwrap();
        let source = dir.path().join("a.png");
        fs::write(&source, b"pixels").unwrap();
        let copy = dir.path().join("out/b.png");
        link_or_copy(&source, &copy).unwrap();
        link_or_copy(&source, &copy).unwrap();
        link_or_copy(&source, &source).unwrap();
        assert_eq!(fs::read(&copy).unwrap(), b"pixels");
        assert_eq!(fs::read(&source).unwrap(), b"pixels");
        let err = link_or_copy(&dir.path().join("none"), &copy).unwrap_err();
        assert!(err.to_string().contains("none"), "{err}");
    }

    #[test]
    fn temporary_names_are_unique_and_name_their_process() {
        let path = Path::new("/x/out.png");
        let (a, b) = (partial_path(path), partial_path(path));
        assert_ne!(a, b);
        let name = a.file_name().unwrap().to_str().unwrap();
        assert!(name.starts_with("out.png.") && name.ends_with(".partial"));
        assert_eq!(partial_owner(name), Some(std::process::id()));
        assert_eq!(partial_owner("out.png"), None);
    }

    #[test]
    fn stale_partials_of_dead_processes_are_removed_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("a/b");
        fs::create_dir_all(&sub).unwrap();
        // Pid 4194304 is above Linux's pid_max, so it never runs.
        let dead = sub.join("x.png.4194304-0.partial");
        let dead_folder = dir.path().join("step-0000001.4194304-3.partial");
        let live = sub.join(format!("y.png.{}-0.partial", std::process::id()));
        fs::write(&dead, b"half").unwrap();
        fs::create_dir_all(dead_folder.join("inner")).unwrap();
        fs::write(&live, b"writing").unwrap();
        fs::write(sub.join("done.png"), b"done").unwrap();
        let expected = if Path::new("/proc").is_dir() { 2 } else { 0 };
        assert_eq!(remove_stale_partials(dir.path()).unwrap(), expected);
        assert_eq!(dead.exists(), expected == 0);
        assert_eq!(dead_folder.exists(), expected == 0);
        assert!(live.exists() && sub.join("done.png").exists());
        assert_eq!(remove_stale_partials(&dir.path().join("none")).unwrap(), 0);
    }
}
