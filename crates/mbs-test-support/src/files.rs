//! Files on disk in tests: empty placeholders and whole-tree snapshots.

use std::path::{Path, PathBuf};

/// Creates an empty file at `path`, with its folders.
pub fn touch(path: &Path) {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).expect("the folders of a test file are created");
    }
    std::fs::write(path, b"").expect("a test file is written");
}

/// Every file under `root` (path relative to it, bytes), sorted: compare
/// two snapshots to check that a command changed nothing, or the same.
pub fn tree(root: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files: Vec<(PathBuf, Vec<u8>)> = walkdir::WalkDir::new(root)
        .into_iter()
        .filter_map(Result::ok)
        .filter(|e| e.file_type().is_file())
        .map(|e| {
            let relative = e.path().strip_prefix(root).unwrap_or(e.path());
            let bytes = std::fs::read(e.path()).expect("a file of the tree is readable");
            (relative.to_path_buf(), bytes)
        })
        .collect();
    files.sort();
    files
}
