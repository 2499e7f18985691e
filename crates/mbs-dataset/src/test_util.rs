//! Helpers of the unit tests.

use std::path::Path;

/// Creates an empty file at `path`, with its folders.
pub(crate) fn touch(path: &Path) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, b"").unwrap();
}
