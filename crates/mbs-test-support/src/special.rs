//! Files that are not regular files, which every writer must refuse to
//! replace: a character device, a FIFO, a socket and a folder, made in a
//! test's own folder so that a writer that failed the test would damage
//! nothing of the machine's.

use std::os::unix::fs::{FileTypeExt, MetadataExt};
use std::os::unix::net::UnixListener;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A file that is not a regular file, and the words a refusal names its
/// kind with.
pub struct SpecialFile {
    /// Where it is.
    pub path: PathBuf,
    /// Its kind as the writers' errors say it ("a character device", ...).
    pub kind: &'static str,
    /// Keeps a socket bound while the test runs.
    _listener: Option<UnixListener>,
}

impl SpecialFile {
    /// Whether `message` refuses this file as the writers do: its path,
    /// its kind and "not a regular file".
    pub fn is_refused_in(&self, message: &str) -> bool {
        message.contains(&self.path.display().to_string())
            && message.contains(self.kind)
            && message.contains("not a regular file")
    }
}

/// A character device, a FIFO, a socket and a folder in `dir`, each named
/// `NAME.EXTENSION` (e.g. `fifo.png`) so that writers that add or check an
/// extension see their own. The device is a copy of `/dev/null` made with
/// `mknod` (as root); a user who may not make devices gets `/dev/null`
/// itself, which such a user cannot replace either.
pub fn special_files(dir: &Path, extension: &str) -> Vec<SpecialFile> {
    let name = |stem: &str| dir.join(format!("{stem}.{extension}"));
    let device = name("device");
    let made = Command::new("mknod")
        .arg(&device)
        .args(["c", "1", "3"])
        .output()
        .is_ok_and(|out| out.status.success());
    let device = if made {
        device
    } else {
        PathBuf::from("/dev/null")
    };
    let fifo = name("fifo");
    let status = Command::new("mkfifo").arg(&fifo).status();
    assert!(
        status.is_ok_and(|s| s.success()),
        "mkfifo {}",
        fifo.display()
    );
    let socket = name("socket");
    let listener = UnixListener::bind(&socket).expect("a socket is bound in the test's folder");
    let folder = name("folder");
    std::fs::create_dir(&folder).expect("a folder is made in the test's folder");
    let file = |path, kind| SpecialFile {
        path,
        kind,
        _listener: None,
    };
    vec![
        file(device, "a character device"),
        file(fifo, "a FIFO"),
        SpecialFile {
            path: socket,
            kind: "a socket",
            _listener: Some(listener),
        },
        file(folder, "a folder"),
    ]
}

/// What identifies a special file: its type, its inode and, for a device,
/// its numbers; equal before and after a refused write when it is untouched.
pub fn identity(path: &Path) -> (bool, bool, bool, bool, u64, u64) {
    let metadata = std::fs::symlink_metadata(path).expect("the special file still exists");
    let kind = metadata.file_type();
    (
        kind.is_char_device(),
        kind.is_fifo(),
        kind.is_socket(),
        kind.is_dir(),
        metadata.ino(),
        metadata.rdev(),
    )
}
