//! The manifest's JSON Schema (`schemas/manifest.schema.json`, embedded at
//! build time) and validation of a JSON document against it.

use std::sync::OnceLock;

/// The manifest JSON Schema text.
pub const MANIFEST_SCHEMA: &str = include_str!("../../../schemas/manifest.schema.json");

/// One place where a document breaks the schema.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SchemaIssue {
    /// JSON pointer to the offending value, e.g. `/samples/3/split`.
    pub pointer: String,
    /// What the schema expected.
    pub message: String,
}

impl SchemaIssue {
    /// The index of the sample the issue is in, if it is inside `samples`.
    pub fn sample_index(&self) -> Option<usize> {
        let rest = self.pointer.strip_prefix("/samples/")?;
        rest.split('/').next()?.parse().ok()
    }
}

fn validator() -> &'static jsonschema::Validator {
    static VALIDATOR: OnceLock<jsonschema::Validator> = OnceLock::new();
    VALIDATOR.get_or_init(|| {
        // The schema is part of this crate and checked by its tests.
        let schema: serde_json::Value =
            serde_json::from_str(MANIFEST_SCHEMA).expect("embedded schema is JSON");
        jsonschema::validator_for(&schema).expect("embedded schema is a valid JSON Schema")
    })
}

/// Every place where `document` breaks the manifest schema (empty if valid).
pub fn manifest_schema_issues(document: &serde_json::Value) -> Vec<SchemaIssue> {
    validator()
        .iter_errors(document)
        .map(|e| SchemaIssue {
            pointer: e.instance_path().to_string(),
            message: e.to_string(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn minimal() -> serde_json::Value {
        json!({
            "format": "mbs-manifest/1",
            "name": "t",
            "rig": {"num_views": 2, "baseline_m": 0.5, "focal_px": 480.0, "cx": 1.5, "cy": 1.0, "width": 4, "height": 3},
            "samples": [{"id": "a", "split": "train", "views": ["a0.png", "a1.png"]}]
        })
    }

    #[test]
    fn minimal_manifest_is_valid() {
        assert_eq!(manifest_schema_issues(&minimal()), vec![]);
    }

    #[test]
    fn bad_split_is_reported_at_its_sample() {
        let mut doc = minimal();
        doc["samples"][0]["split"] = json!("training");
        let issues = manifest_schema_issues(&doc);
        assert_eq!(issues.len(), 1, "{issues:?}");
        assert_eq!(issues[0].pointer, "/samples/0/split");
        assert_eq!(issues[0].sample_index(), Some(0));
    }

    #[test]
    fn absolute_paths_and_unknown_fields_are_refused() {
        let mut doc = minimal();
        doc["samples"][0]["views"][0] = json!("/abs/a0.png");
        doc["rig"]["colour"] = json!(true);
        let pointers: Vec<String> = manifest_schema_issues(&doc)
            .into_iter()
            .map(|i| i.pointer)
            .collect();
        assert!(
            pointers.contains(&"/samples/0/views/0".to_string()),
            "{pointers:?}"
        );
        assert!(pointers.contains(&"/rig".to_string()), "{pointers:?}");
    }
}
