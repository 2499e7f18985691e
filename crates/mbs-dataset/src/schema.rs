//! JSON Schemas embedded at build time, compiled on first use: the
//! manifest's (`schemas/manifest.schema.json`) and any other crate's (the
//! training configuration's), and validation of a document against them.

use std::sync::OnceLock;

use serde_json::Value;

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

/// A JSON Schema whose text is part of a crate (`include_str!`), compiled
/// the first time a document is checked.
pub struct EmbeddedSchema {
    text: &'static str,
    compiled: OnceLock<jsonschema::Validator>,
}

impl EmbeddedSchema {
    /// A schema from its text; the owning crate's tests must check that
    /// the text is a valid JSON Schema.
    pub const fn new(text: &'static str) -> Self {
        Self {
            text,
            compiled: OnceLock::new(),
        }
    }

    /// Every place where `document` breaks the schema (empty if valid).
    pub fn issues(&self, document: &Value) -> Vec<SchemaIssue> {
        let validator = self.compiled.get_or_init(|| {
            // Embedded schemas are part of their crates and checked by their tests.
            let schema: Value = serde_json::from_str(self.text).expect("embedded schema is JSON");
            jsonschema::validator_for(&schema).expect("embedded schema is a valid JSON Schema")
        });
        validator
            .iter_errors(document)
            .map(|e| SchemaIssue {
                pointer: e.instance_path().to_string(),
                message: match e.kind() {
                    jsonschema::error::ValidationErrorKind::Pattern { .. } => {
                        pattern_message(e.instance(), &e.schema_path().to_string())
                    }
                    _ => e.to_string(),
                },
            })
            .collect()
    }
}

/// A broken pattern in words: the pattern itself is unreadable, so a
/// confined name (`/$defs/name`) gets the rule's own reason, any other
/// string the pattern's place in the schema.
fn pattern_message(instance: &Value, schema_path: &str) -> String {
    let reason = instance
        .as_str()
        .filter(|_| schema_path.contains("/$defs/name/"))
        .and_then(|name| mbs_core::confine::check_name(name).err());
    match reason {
        Some(why) => {
            format!("{instance} {why} (paths and ids are confined names, see the schema's `name`)")
        }
        None => format!("{instance} breaks the rule at {schema_path} in the schema"),
    }
}

static MANIFEST: EmbeddedSchema = EmbeddedSchema::new(MANIFEST_SCHEMA);

/// Every place where `document` breaks the manifest schema (empty if valid).
pub fn manifest_schema_issues(document: &Value) -> Vec<SchemaIssue> {
    MANIFEST.issues(document)
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

    #[test]
    fn the_name_pattern_states_the_confinement_rule() {
        let names = [
            "a.png",
            "Town01/ClearNoon/000123",
            "..hidden",
            "a/...",
            ".config",
            "with space.png",
            "é/ü.png",
            "",
            ".",
            "..",
            "/abs/a.png",
            "../a.png",
            "a/../../b",
            "a/..",
            "./a",
            "a//b",
            "a/",
            "a\\b",
            "C:x",
            "a\nb",
            "a\u{7f}b",
        ];
        for name in names {
            let mut doc = minimal();
            doc["samples"][0]["id"] = json!(name);
            doc["samples"][0]["views"][1] = json!(name);
            let issues = manifest_schema_issues(&doc);
            let mut pointers: Vec<&str> = issues.iter().map(|i| i.pointer.as_str()).collect();
            pointers.dedup();
            let rule = mbs_core::confine::check_name(name);
            // An accepted name passes the schema in both places; a refused
            // one is reported at the id and at the view.
            let expected = if rule.is_ok() {
                vec![]
            } else {
                vec!["/samples/0/id", "/samples/0/views/1"]
            };
            assert_eq!(pointers, expected, "{name:?}: {issues:?}");
        }
    }
}
