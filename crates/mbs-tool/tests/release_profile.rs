//! The release profile a user's `cargo build --release` gets (issue 26):
//! no debug info in the binary (line tables made it 569 MB instead of
//! 106 MB, BENCHMARKS.md "Release binary") and unwinding panics, which the
//! GPU device probe relies on to turn a runtime's panic into one error.
#![allow(clippy::unwrap_used)]

/// The `[profile.release]` section of the workspace manifest, one
/// `key = value` line each.
fn release_profile() -> Vec<(String, String)> {
    let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../Cargo.toml");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let section = text
        .split("\n[")
        .find(|section| section.starts_with("profile.release]"))
        .expect("the workspace manifest has a [profile.release] section");
    section
        .lines()
        .skip(1)
        .filter_map(|line| line.split_once('='))
        .map(|(key, value)| (key.trim().to_string(), value.trim().to_string()))
        .collect()
}

#[test]
fn the_release_binary_carries_no_debug_info_and_unwinds() {
    let profile = release_profile();
    let get = |key: &str| {
        profile
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    };
    assert_eq!(get("debug"), Some("false"), "{profile:?}");
    assert_eq!(get("strip"), Some("\"debuginfo\""), "{profile:?}");
    assert_ne!(get("panic"), Some("\"abort\""), "{profile:?}");
}
