//! Files on disk in tests: empty placeholders, whole-tree snapshots, and
//! what can safely be looked at while another process is still writing.

use std::path::{Path, PathBuf};

/// Creates an empty file at `path`, with its folders.
pub fn touch(path: &Path) {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).expect("the folders of a test file are created");
    }
    std::fs::write(path, b"").expect("a test file is written");
}

/// Whether `entry` is one of the files mbs keeps about an output folder
/// (`.mbs-lock*`, the holder's name and time; `.mbs-written*`, the record
/// of its outputs), which differ between runs that write the same outputs
/// (another process, another shard) and are not outputs themselves.
fn is_bookkeeping(entry: &walkdir::DirEntry) -> bool {
    entry
        .file_name()
        .to_str()
        .is_some_and(|name| name.starts_with(".mbs-lock") || name.starts_with(".mbs-written"))
}

/// Every file under `root` (path relative to it, bytes), sorted, but mbs's
/// bookkeeping files (`.mbs-lock*`, `.mbs-written*`): compare two snapshots to check
/// that a command changed nothing, or the same.
pub fn tree(root: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files: Vec<(PathBuf, Vec<u8>)> = walkdir::WalkDir::new(root)
        .into_iter()
        .filter_map(Result::ok)
        .filter(|e| e.file_type().is_file() && !is_bookkeeping(e))
        .map(|e| {
            let relative = e.path().strip_prefix(root).unwrap_or(e.path());
            let bytes = std::fs::read(e.path()).expect("a file of the tree is readable");
            (relative.to_path_buf(), bytes)
        })
        .collect();
    files.sort();
    files
}

/// How many files are under `root` now (mbs's bookkeeping files left out,
/// as in [`tree`]), without reading any: safe while another process writes
/// there (an entry renamed or removed meanwhile is skipped, where [`tree`]
/// would fail to read it).
pub fn file_count(root: &Path) -> usize {
    walkdir::WalkDir::new(root)
        .into_iter()
        .filter_map(Result::ok)
        .filter(|e| e.file_type().is_file() && !is_bookkeeping(e))
        .count()
}

/// The complete lines of a text file another process appends to: none when
/// it does not exist yet, and a last line without its newline (still being
/// written) left out.
pub fn complete_lines(path: &Path) -> Vec<String> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Vec::new();
    };
    let complete = text.rfind('\n').map_or("", |end| &text[..end]);
    complete.lines().map(str::to_string).collect()
}
