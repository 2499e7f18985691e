//! Seeded mutations of the paper's training configuration as a file:
//! reading it never panics and names the file on error; layering and
//! checking what was read never panic (the CLI names the file around
//! those errors, as here).

use mbs_test_support::mutation::fuzz_reader;
use mbs_train::config::RunConfig;

#[test]
fn mutated_configs_never_panic_and_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let valid = serde_json::to_string_pretty(&RunConfig::paper().to_json().unwrap()).unwrap();
    let summary = fuzz_reader(valid.as_bytes(), dir.path(), "json", (1500, 3), |path| {
        let file = RunConfig::read_file(path).map_err(|e| e.to_string())?;
        RunConfig::layered(Some(&file), &[])
            .map(drop)
            .map_err(|e| format!("settings from {}: {e}", path.display()))
    })
    .unwrap();
    assert_eq!(summary.failures, Vec::<String>::new());
    assert!(summary.refused > summary.cases / 3, "{summary:?}");
}
