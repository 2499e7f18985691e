//! Opening files only when they are regular files, without ever blocking:
//! a FIFO, a device, a socket or a folder given where a file belongs (also
//! behind a chain of symbolic links) is refused with an error naming the
//! path and what it is, instead of a read that waits for a writer for ever
//! or a log appended to a device.
//!
//! On Unix the file is opened with `O_NONBLOCK` (opening a FIFO then
//! returns at once) and its type is checked on the open handle, so a file
//! swapped between a check and the open cannot slip through; the flag
//! changes nothing for a regular file's reads and writes.

use std::fs;
use std::io::Read;
use std::path::Path;

use crate::error::{FormatError, Result};

/// Opens `path` for reading, refusing anything but a regular file.
pub fn open_regular(path: &Path) -> Result<fs::File> {
    checked(path, fs::OpenOptions::new().read(true))
}

/// Opens `path` for appending, made when missing (its folder must exist),
/// refusing anything but a regular file.
pub fn open_append(path: &Path) -> Result<fs::File> {
    checked(path, fs::OpenOptions::new().create(true).append(true))
}

/// `path` opened with `options` and `O_NONBLOCK`, when it is a regular file.
fn checked(path: &Path, options: &mut fs::OpenOptions) -> Result<fs::File> {
    let file = match open_without_blocking(path, options) {
        Ok(file) => file,
        // A socket cannot be opened at all: say what it is.
        Err(e) => match fs::metadata(path) {
            Ok(metadata) if !metadata.is_file() => return Err(not_regular(path, &metadata)),
            _ => return Err(FormatError::io(path, e)),
        },
    };
    let metadata = file.metadata().map_err(|e| FormatError::io(path, e))?;
    if metadata.is_file() {
        Ok(file)
    } else {
        Err(not_regular(path, &metadata))
    }
}

/// The refusal of `path`, which `metadata` shows is not a regular file.
fn not_regular(path: &Path, metadata: &fs::Metadata) -> FormatError {
    FormatError::invalid(
        path,
        format!("is {}, not a regular file", describe(&metadata.file_type())),
    )
}

/// The whole of the regular file `path`.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    let mut file = open_regular(path)?;
    let mut bytes = Vec::new();
    file.read_to_end(&mut bytes)
        .map_err(|e| FormatError::io(path, e))?;
    Ok(bytes)
}

/// The whole of the regular file `path` as UTF-8 text.
pub fn read_text(path: &Path) -> Result<String> {
    String::from_utf8(read_bytes(path)?)
        .map_err(|_| FormatError::invalid(path, "is not UTF-8 text"))
}

/// [`read_text`], or `None` when nothing is at `path` (also a link to
/// nothing); anything else that cannot be read is an error naming it.
pub fn read_text_if_present(path: &Path) -> Result<Option<String>> {
    match read_text(path) {
        Err(FormatError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
            Ok(None)
        }
        other => other.map(Some),
    }
}

#[cfg(unix)]
fn open_without_blocking(path: &Path, options: &mut fs::OpenOptions) -> std::io::Result<fs::File> {
    use std::os::unix::fs::OpenOptionsExt;
    options
        .custom_flags(rustix::fs::OFlags::NONBLOCK.bits() as i32)
        .open(path)
}

#[cfg(not(unix))]
fn open_without_blocking(path: &Path, options: &mut fs::OpenOptions) -> std::io::Result<fs::File> {
    options.open(path)
}

/// Why `path`, the user's `what` (e.g. "left view", "manifest"), cannot
/// be read as a file before any work starts: it is a folder, another kind
/// of file (a FIFO, a socket, a device: named as [`describe`] names it),
/// or does not exist; `None` when it is a regular file. The file is not
/// opened (a FIFO's open could wait for a writer). The message names the
/// path, as the commands print it.
pub fn not_a_file(path: &Path, what: &str) -> Option<String> {
    match fs::metadata(path) {
        Ok(metadata) if metadata.is_file() => None,
        Ok(metadata) if metadata.is_dir() => Some(format!(
            "{}: is a folder, the {what} must be a file",
            path.display()
        )),
        Ok(metadata) => Some(format!(
            "{}: is {}, not a regular file (the {what})",
            path.display(),
            describe(&metadata.file_type())
        )),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            Some(format!("{}: no such file (the {what})", path.display()))
        }
        Err(e) => Some(format!("{}: {e} (the {what})", path.display())),
    }
}

/// What a file that is not a regular file is, in words: "a folder", "a
/// FIFO (named pipe)", …
pub fn describe(kind: &fs::FileType) -> &'static str {
    if kind.is_dir() {
        return "a folder";
    }
    special_kind(kind)
}

#[cfg(unix)]
fn special_kind(kind: &fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_char_device() {
        "a character device"
    } else if kind.is_block_device() {
        "a block device"
    } else if kind.is_fifo() {
        "a FIFO (named pipe)"
    } else if kind.is_socket() {
        "a socket"
    } else {
        "a special file"
    }
}

#[cfg(not(unix))]
fn special_kind(_: &fs::FileType) -> &'static str {
    "a special file"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_a_regular_file_and_names_a_missing_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("calib.txt");
        fs::write(&path, "ndisp=64\n").unwrap();
        assert_eq!(read_text(&path).unwrap(), "ndisp=64\n");
        let err = read_bytes(&dir.path().join("none.txt")).unwrap_err();
        assert!(err.to_string().contains("none.txt"), "{err}");
        assert_eq!(
            read_text_if_present(&dir.path().join("none.txt")).unwrap(),
            None
        );
        assert_eq!(
            read_text_if_present(&path).unwrap().as_deref(),
            Some("ndisp=64\n")
        );
        fs::write(&path, [0xff, 0xfe]).unwrap();
        let err = read_text(&path).unwrap_err().to_string();
        assert!(err.contains("calib.txt: is not UTF-8"), "{err}");
    }

    /// A FIFO with no writer, also behind two links, a device, a socket
    /// and a folder are refused at once (a plain read of the FIFO would
    /// block for ever), each error naming the path and its kind.
    #[cfg(unix)]
    #[test]
    fn special_files_are_refused_without_blocking() {
        use mbs_test_support::special::special_files;
        let dir = tempfile::tempdir().unwrap();
        let special = special_files(dir.path(), "txt");
        let fifo = special
            .iter()
            .find(|f| f.kind.contains("FIFO"))
            .expect("special_files makes a FIFO");
        let first = dir.path().join("first.txt");
        let second = dir.path().join("second.txt");
        std::os::unix::fs::symlink(&fifo.path, &second).unwrap();
        std::os::unix::fs::symlink(&second, &first).unwrap();
        let cases = special
            .iter()
            .map(|f| (f.path.clone(), f.kind))
            .chain([(first, fifo.kind)]);
        for (path, kind) in cases {
            let (done, outcome) = std::sync::mpsc::channel();
            let probe = path.clone();
            std::thread::spawn(move || done.send(read_bytes(&probe).map(|_| ())));
            let err = outcome
                .recv_timeout(std::time::Duration::from_secs(10))
                .unwrap_or_else(|_| panic!("reading {} blocked", path.display()))
                .unwrap_err()
                .to_string();
            assert!(err.contains(&path.display().to_string()), "{err}");
            assert!(
                err.contains(kind) && err.contains("not a regular file"),
                "{err}"
            );
            let err = open_append(&path).unwrap_err().to_string();
            assert!(
                err.contains(kind) && err.contains("not a regular file"),
                "{err}"
            );
        }
        let log = dir.path().join("train.jsonl");
        std::io::Write::write_all(&mut open_append(&log).unwrap(), b"{}\n").unwrap();
        std::io::Write::write_all(&mut open_append(&log).unwrap(), b"{}\n").unwrap();
        assert_eq!(read_text(&log).unwrap(), "{}\n{}\n");
    }

    /// `not_a_file` names what a special file is, without opening it (a
    /// FIFO's open would wait for a writer): it used to call a FIFO or a
    /// socket "no such file".
    #[cfg(unix)]
    #[test]
    fn not_a_file_names_the_kind_of_a_special_file() {
        use mbs_test_support::special::special_files;
        let dir = tempfile::tempdir().unwrap();
        for special in special_files(dir.path(), "json") {
            let message = not_a_file(&special.path, "manifest").expect("refused");
            let path = special.path.display().to_string();
            assert!(message.starts_with(&path), "{message}");
            assert!(message.contains(special.kind), "{message}");
            assert!(!message.contains("no such file"), "{message}");
        }
        let file = dir.path().join("manifest.json");
        assert_eq!(
            not_a_file(&file, "manifest").as_deref(),
            Some(format!("{}: no such file (the manifest)", file.display()).as_str())
        );
        fs::write(&file, "{}").unwrap();
        assert_eq!(not_a_file(&file, "manifest"), None);
    }
}
