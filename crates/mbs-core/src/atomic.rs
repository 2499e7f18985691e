//! Crash-safe file writing: write to a temporary name beside the target, then
//! rename. A killed process (crash, Ctrl-C, `kill -9`) leaves at most a
//! `*.partial` file, never a truncated file under the final name that a
//! re-run would trust. Files are not fsync'ed: that would guard against a
//! power cut too, at several milliseconds per file.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{FormatError, Result};

/// Suffix of in-progress files. A re-run overwrites stale ones.
pub const PARTIAL_SUFFIX: &str = ".partial";

/// The temporary name used while `path` is being written.
pub fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(PARTIAL_SUFFIX);
    path.with_file_name(name)
}

/// Writes `path` atomically: `write` fills a buffered writer on a temporary
/// file, which is flushed and renamed to `path` only on success.
/// Parent folders are created as needed.
pub fn write_atomic<F>(path: &Path, write: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<fs::File>) -> std::io::Result<()>,
{
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        fs::create_dir_all(parent).map_err(|e| FormatError::io(parent, e))?;
    }
    let partial = partial_path(path);
    let result = (|| {
        let file = fs::File::create(&partial)?;
        let mut writer = BufWriter::with_capacity(1 << 20, file);
        write(&mut writer)?;
        writer.flush()?;
        drop(writer);
        fs::rename(&partial, path)
    })();
    result.map_err(|e| {
        // Best effort: the partial file is garbage either way.
        let _ = fs::remove_file(&partial);
        FormatError::io(path, e)
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
}
