//! Every shipped model card (built-in and test fixtures) satisfies
//! `schemas/model-card.schema.json` and parses into a checked `ModelCard`,
//! and every card file in `models/cards` is built in under its file name.

use std::path::{Path, PathBuf};

use mbs_infer::onnx::ModelCard;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn json_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    files
}

#[test]
fn shipped_cards_follow_the_schema() {
    let schema: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root().join("schemas/model-card.schema.json")).unwrap(),
    )
    .unwrap();
    let validator = jsonschema::validator_for(&schema).unwrap();
    let cards: Vec<PathBuf> = [
        json_files(&root().join("crates/mbs-infer/models/cards")),
        json_files(&root().join("testdata/onnx")),
    ]
    .concat();
    // 11 built-in cards (6 stereo and inpainting, FastDepth, Depth Anything
    // V2 small, base and large, MiDaS v2.1 small) and 6 test fixtures.
    assert_eq!(cards.len(), 17);
    for path in cards {
        let document: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let issues: Vec<String> = validator
            .iter_errors(&document)
            .map(|e| e.to_string())
            .collect();
        assert!(issues.is_empty(), "{}: {issues:?}", path.display());
        ModelCard::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
    }
    // The schema refuses what the loader refuses.
    let bad = serde_json::json!({"name": "x", "task": "stereo", "inputs": {"left": "l"},
        "size": {"mode": "dynamic", "multiple": 0}, "output": {"name": "d", "sign": 2}});
    assert_eq!(validator.iter_errors(&bad).count(), 2);
}

#[test]
fn every_card_file_is_built_in_under_its_name() {
    let dir = root().join("crates/mbs-infer/models/cards");
    let mut files: Vec<String> = json_files(&dir)
        .iter()
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    let mut builtin: Vec<String> = ModelCard::builtin_names().map(String::from).collect();
    files.sort();
    builtin.sort();
    assert_eq!(files, builtin);
}
