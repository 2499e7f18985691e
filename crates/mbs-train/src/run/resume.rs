//! Whether a checkpoint may be resumed under a new configuration: only
//! settings that do not change what is computed may differ.

use serde_json::Value;

use crate::checkpoint::Checkpoint;
use crate::config::RunConfig;
use crate::error::TrainError;

/// Keys that may change between a run and its resumption: they do not
/// change what is computed.
const OPERATIONAL_KEYS: [&str; 6] = [
    "log_every",
    "val_every",
    "checkpoint_every",
    "keep_checkpoints",
    "visual_samples",
    "data",
];

/// Refuses to resume `checkpoint` under a configuration that computes
/// something else (only the keys in [`OPERATIONAL_KEYS`] may differ, and
/// `data` only in its loading and validation settings).
pub(crate) fn check_resumable(
    checkpoint: &Checkpoint,
    config: &RunConfig,
) -> Result<(), TrainError> {
    // Through the settings type, so a key added since the checkpoint was
    // written takes its default (the value older runs were trained with).
    let differing = computing_differences(&checkpoint.config()?, config)?;
    if !differing.is_empty() {
        return Err(TrainError::checkpoint(
            &checkpoint.dir,
            format!(
                "was trained with other settings ({}); use a new --out, or --restart to discard it",
                differing.join(", ")
            ),
        ));
    }
    Ok(())
}

/// The settings that differ between `from` and `to` and change what is
/// computed (all but the keys in [`OPERATIONAL_KEYS`]), each as `path:
/// from-value -> to-value`.
pub fn computing_differences(from: &RunConfig, to: &RunConfig) -> Result<Vec<String>, TrainError> {
    let strip = |mut value: Value| {
        if let Value::Object(map) = &mut value {
            for key in OPERATIONAL_KEYS {
                if key == "data" {
                    if let Some(Value::Object(data)) = map.get_mut("data") {
                        for operational in [
                            "workers",
                            "val_pairs",
                            "val_samples",
                            "val_split",
                            "val_protocol",
                        ] {
                            data.remove(operational);
                        }
                    }
                } else {
                    map.remove(key);
                }
            }
        }
        value
    };
    let mut differing = Vec::new();
    diff(
        &strip(from.to_json()?),
        &strip(to.to_json()?),
        "",
        &mut differing,
    );
    Ok(differing)
}

/// Dotted paths where `a` and `b` differ.
fn diff(a: &Value, b: &Value, prefix: &str, out: &mut Vec<String>) {
    match (a, b) {
        (Value::Object(a), Value::Object(b)) => {
            for key in a.keys().chain(b.keys().filter(|k| !a.contains_key(*k))) {
                let path = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                match (a.get(key), b.get(key)) {
                    (Some(x), Some(y)) => diff(x, y, &path, out),
                    (Some(x), None) => out.push(format!("{path}: {x} -> missing")),
                    (None, Some(y)) => out.push(format!("{path}: missing -> {y}")),
                    (None, None) => {}
                }
            }
        }
        (a, b) if a != b => out.push(format!("{prefix}: {a} -> {b}")),
        _ => {}
    }
}
