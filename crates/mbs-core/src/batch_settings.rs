//! The settings a batch command wrote an output folder's files with, kept in
//! the folder (`.mbs-settings-COMMAND.json`). A resumed run skips the files
//! that exist, so a second run with other settings (another seed, another
//! model) would mix two kinds of file in one dataset; it is refused
//! instead, saying what differs, before anything is written.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::error::{FormatError, Result};

/// The settings file of `command` in the folder `root`.
pub fn settings_file(root: &Path, command: &str) -> PathBuf {
    root.join(format!(".mbs-settings-{command}.json"))
}

/// Refuses `settings` when the folder `root` holds files `command` wrote
/// with other settings, naming each setting that differs; a folder without
/// a settings file passes.
pub fn check(root: &Path, command: &str, settings: &Value) -> Result<()> {
    let path = settings_file(root, command);
    if !path.exists() {
        return Ok(());
    }
    let text = crate::regular::read_text(&path)?;
    let kept: Value = serde_json::from_str(&text)
        .map_err(|e| FormatError::invalid(&path, format!("not valid JSON: {e}")))?;
    if &kept == settings {
        return Ok(());
    }
    let differences = differences(&kept, settings).join("; ");
    Err(FormatError::invalid(
        root,
        format!(
            "holds files an earlier `mbs-tool {command}` wrote with other settings ({differences}); \
             a run resumes only with the same settings: choose another output folder"
        ),
    ))
}

/// Keeps `settings` as the folder's (once [`check`] passed and the folder
/// is held).
pub fn keep(root: &Path, command: &str, settings: &Value) -> Result<()> {
    let text = serde_json::to_string_pretty(settings)
        .map_err(|e| FormatError::invalid(root, e.to_string()))?;
    crate::atomic::write_bytes_atomic(&settings_file(root, command), text.as_bytes())
}

/// `was` against `now`, a phrase per top-level setting that differs.
fn differences(was: &Value, now: &Value) -> Vec<String> {
    let (Some(was), Some(now)) = (was.as_object(), now.as_object()) else {
        return vec![format!("was {was}, now {now}")];
    };
    let mut keys: Vec<&String> = was.keys().chain(now.keys()).collect();
    keys.sort();
    keys.dedup();
    keys.into_iter()
        .filter(|key| was.get(*key) != now.get(*key))
        .map(|key| {
            let show = |v: Option<&Value>| v.map_or("none".to_string(), Value::to_string);
            format!(
                "{key}: was {}, now {}",
                show(was.get(key)),
                show(now.get(key))
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn other_settings_are_refused_naming_what_differs() {
        let dir = tempfile::tempdir().unwrap();
        let first = serde_json::json!({ "seed": 7, "views": 4 });
        check(dir.path(), "mono", &first).unwrap();
        keep(dir.path(), "mono", &first).unwrap();
        check(dir.path(), "mono", &first).unwrap();
        let other = serde_json::json!({ "seed": 8, "views": 4 });
        let err = check(dir.path(), "mono", &other).unwrap_err().to_string();
        assert!(
            err.contains("seed: was 7, now 8") && !err.contains("views"),
            "{err}"
        );
        assert!(err.contains("choose another output folder"), "{err}");
        // Another command's settings are its own.
        check(dir.path(), "extrapolate", &other).unwrap();
    }
}
