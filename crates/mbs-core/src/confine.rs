//! The one rule for names that come from data (manifest paths, sample ids,
//! town names) and become paths: a *confined name* is relative, uses `/`
//! between segments, and never leaves the folder it is joined to.
//!
//! Precisely: it is not empty, has at most [`MAX_NAME_LEN`] characters, does not
//! start or end with `/`, and each `/`-separated segment is non-empty, is
//! neither `.` nor `..`, and holds no `\`, `:` or control character. The
//! manifest schema's `name` pattern states the same rule.
//!
//! Every output path built from such a name goes through [`join_confined`],
//! so no input can make a command write outside its `--out`.

use std::path::{Path, PathBuf};

use crate::error::{FormatError, Result};

/// The longest confined name, in characters.
pub const MAX_NAME_LEN: usize = 1024;

/// Checks `name` against the rule above; the error says which part breaks it.
pub fn check_name(name: &str) -> std::result::Result<(), String> {
    if name.is_empty() {
        return Err("is empty".into());
    }
    if name.chars().count() > MAX_NAME_LEN {
        return Err(format!("is longer than {MAX_NAME_LEN} characters"));
    }
    if name.starts_with('/') {
        return Err("is absolute (names are relative to their folder)".into());
    }
    for segment in name.split('/') {
        match segment {
            "" => return Err("has an empty segment (a doubled or trailing '/')".into()),
            "." | ".." => {
                return Err(format!(
                    "has a {segment:?} segment (names must stay inside their folder)"
                ));
            }
            _ => {}
        }
        if let Some(c) = segment
            .chars()
            .find(|c| *c == '\\' || *c == ':' || c.is_control())
        {
            return Err(format!("holds the character {c:?}"));
        }
    }
    Ok(())
}

/// `root` joined with the confined `name`; an error names `name` and the
/// rule it breaks.
pub fn join_confined(root: &Path, name: &str) -> Result<PathBuf> {
    check_name(name).map_err(|why| {
        FormatError::invalid(
            Path::new(name),
            format!("{why}; cannot place it inside {}", root.display()),
        )
    })?;
    Ok(root.join(name))
}

/// `path` relative to `root` as a confined name, when `path` lies inside
/// `root` (compared component by component, without touching the disk).
pub fn name_inside(root: &Path, path: &Path) -> Option<String> {
    let rest = path.strip_prefix(root).ok()?;
    let name = rest
        .components()
        .map(|c| c.as_os_str().to_str())
        .collect::<Option<Vec<_>>>()?
        .join("/");
    check_name(&name).ok().map(|()| name)
}

/// Creates the output folder `dir` (and its parents); a file in its place
/// is an error that says so.
pub fn create_out_dir(dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(FormatError::invalid(
            dir,
            "exists and is not a folder (--out must name a folder)",
        ));
    }
    std::fs::create_dir_all(dir).map_err(|e| FormatError::io(dir, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Names and whether the rule accepts them; the manifest schema's
    /// pattern is checked against the same table in mbs-dataset.
    const CASES: &[(&str, bool)] = &[
        ("a.png", true),
        ("Town01/ClearNoon/000123", true),
        ("image_2/000000_10.png", true),
        ("..hidden", true),
        ("a/...", true),
        (".config", true),
        ("with space.png", true),
        ("", false),
        ("/abs/a.png", false),
        ("../a.png", false),
        ("a/../../b", false),
        ("a/..", false),
        ("./a", false),
        ("a//b", false),
        ("a/", false),
        ("a\\b", false),
        ("C:x", false),
        ("a\nb", false),
    ];

    #[test]
    fn the_rule_accepts_and_refuses_as_documented() {
        for (name, ok) in CASES {
            assert_eq!(check_name(name).is_ok(), *ok, "{name:?}");
        }
    }

    #[test]
    fn joins_stay_inside_their_root() {
        let root = Path::new("/out");
        assert_eq!(
            join_confined(root, "a/b.png").unwrap(),
            Path::new("/out/a/b.png")
        );
        let err = join_confined(root, "../../etc/x").unwrap_err().to_string();
        assert!(
            err.contains("../../etc/x") && err.contains("\"..\""),
            "{err}"
        );
        assert!(join_confined(root, "/etc/x").is_err());
    }

    #[test]
    fn names_inside_a_root() {
        let root = Path::new("/data/set");
        assert_eq!(
            name_inside(root, Path::new("/data/set/a/b.png")).as_deref(),
            Some("a/b.png")
        );
        assert_eq!(name_inside(root, Path::new("/data/other/b.png")), None);
    }

    #[test]
    fn a_file_as_out_dir_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("f");
        std::fs::write(&file, b"x").unwrap();
        let err = create_out_dir(&file).unwrap_err().to_string();
        assert!(err.contains("is not a folder"), "{err}");
        create_out_dir(&dir.path().join("new/deep")).unwrap();
        assert!(dir.path().join("new/deep").is_dir());
    }
}
