//! Seeded mutations of a built-in model card read as a file: never a
//! panic, and every error names the card file.

use mbs_infer::onnx::ModelCard;
use mbs_test_support::mutation::fuzz_reader;

#[test]
fn mutated_cards_never_panic_and_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let name = ModelCard::builtin_names().next().unwrap();
    let valid = serde_json::to_string_pretty(&ModelCard::load(name).unwrap()).unwrap();
    let summary = fuzz_reader(valid.as_bytes(), dir.path(), "json", (1500, 5), |path| {
        ModelCard::from_file(path).map(drop)
    })
    .unwrap();
    assert_eq!(summary.failures, Vec::<String>::new());
    assert!(summary.refused > summary.cases / 2, "{summary:?}");
}
