//! Settings in layers, as JSON documents: the defaults, then a file with
//! any subset of the keys, then `key.path=value` overrides of existing
//! keys. The trainer's run configuration and the networks' configurations
//! are built this way; errors are sentences each caller wraps in its own
//! configuration error.

use serde_json::Value;

/// Overlays `top` on `base`: objects merge key by key, anything else replaces.
pub fn merge(base: &mut Value, top: &Value) {
    match (base, top) {
        (Value::Object(base), Value::Object(top)) => {
            for (key, value) in top {
                match base.get_mut(key) {
                    Some(slot) => merge(slot, value),
                    None => {
                        base.insert(key.clone(), value.clone());
                    }
                }
            }
        }
        (base, top) => *base = top.clone(),
    }
}

/// `a.b.c=value` into the path and a JSON value (`value` is parsed as JSON
/// when it is, e.g. `3`, `false`, `[[0,1]]`, and taken as a string otherwise).
pub fn parse_override(assignment: &str) -> Result<(Vec<String>, Value), String> {
    let (path, raw) = assignment.split_once('=').ok_or_else(|| {
        format!("override `{assignment}` is not KEY=VALUE (e.g. trainer.loss.omega=3)")
    })?;
    let path: Vec<String> = path.trim().split('.').map(str::to_owned).collect();
    if path.iter().any(String::is_empty) {
        return Err(format!("override `{assignment}`: empty key in the path"));
    }
    let value = serde_json::from_str(raw.trim()).unwrap_or_else(|_| Value::String(raw.into()));
    Ok((path, value))
}

/// Sets an existing key of `document`; unknown keys are an error naming the
/// keys that exist there.
pub fn set_path(document: &mut Value, path: &[String], value: Value) -> Result<(), String> {
    let mut slot = document;
    for (depth, key) in path.iter().enumerate() {
        let Value::Object(map) = slot else {
            return Err(format!("`{}` is not a section", path[..depth].join(".")));
        };
        let known: Vec<String> = map.keys().cloned().collect();
        slot = map.get_mut(key).ok_or_else(|| {
            format!(
                "unknown key `{}`; known here: {}",
                path[..=depth].join("."),
                known.join(", ")
            )
        })?;
    }
    merge(slot, &value);
    Ok(())
}

/// `document` overlaid with each `key.path=value` of `overrides`
/// ([`parse_override`], [`set_path`]).
pub fn apply_overrides(document: &mut Value, overrides: &[String]) -> Result<(), String> {
    for assignment in overrides {
        let (path, value) = parse_override(assignment)?;
        set_path(document, &path, value)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn overrides_set_existing_keys_and_parse_json_values() {
        let mut document = json!({"a": {"b": 1, "c": "x"}, "d": [1]});
        let overrides = ["a.b=3".to_string(), "a.c=word".into(), "d=[2,3]".into()];
        apply_overrides(&mut document, &overrides).unwrap();
        assert_eq!(document, json!({"a": {"b": 3, "c": "word"}, "d": [2, 3]}));
        let err = apply_overrides(&mut document, &["a.z=1".into()]).unwrap_err();
        assert_eq!(err, "unknown key `a.z`; known here: b, c");
        let err = apply_overrides(&mut document, &["a.b.c=1".into()]).unwrap_err();
        assert_eq!(err, "`a.b` is not a section");
        assert!(parse_override("a..b=1").unwrap_err().contains("empty key"));
        assert!(
            parse_override("ab")
                .unwrap_err()
                .contains("is not KEY=VALUE")
        );
    }

    #[test]
    fn files_merge_key_by_key() {
        let mut base = json!({"a": {"b": 1, "c": 2}});
        merge(&mut base, &json!({"a": {"c": 5}, "e": true}));
        assert_eq!(base, json!({"a": {"b": 1, "c": 5}, "e": true}));
    }
}
