//! The configuration of a training run: every hyper-parameter, with the
//! paper's defaults, as one JSON document (`schemas/train-config.schema.json`).
//!
//! A run's configuration is built in layers: the defaults, then a user's
//! file (any subset of the keys), then `key.path=value` overrides; the
//! result is checked against the schema and then against each part's
//! ranges.

use burn::config::Config;
use mbs_core::layered;
use mbs_dataset::schema::EmbeddedSchema;
use serde_json::Value;

use crate::augment::AugmentConfig;
use crate::data::DataConfig;
use crate::error::TrainError;
use crate::losses::LossConfig;
use crate::schedule::OneCycleConfig;
use crate::step::TrainerConfig;
use mbs_nets::{BackboneKind, NetworkConfig, ranges};

/// The training configuration JSON Schema text.
pub const TRAIN_CONFIG_SCHEMA: &str = include_str!("../../../schemas/train-config.schema.json");

/// Everything a training run needs to know besides its data and output.
#[derive(Config, Debug)]
pub struct RunConfig {
    /// Loss, learning rate, EMA and clipping.
    pub trainer: TrainerConfig,
    /// The backbone.
    pub network: NetworkConfig,
    /// The student's augmentation.
    pub augment: AugmentConfig,
    /// Batches, crops, loading and validation pairs.
    pub data: DataConfig,
    /// Seed of the weights and of every random choice of the run.
    #[config(default = 0)]
    pub seed: u64,
    /// Log the loss terms every this many steps.
    #[config(default = 20)]
    pub log_every: usize,
    /// Validate (and draw the visual outputs) every this many steps, and at the end.
    #[config(default = 1000)]
    pub val_every: usize,
    /// Save a checkpoint every this many steps, and at the end or on a stop.
    #[config(default = 5000)]
    pub checkpoint_every: usize,
    /// Checkpoints kept on disk (the newest ones).
    #[config(default = 2)]
    pub keep_checkpoints: usize,
    /// Validation pairs drawn as contact sheets.
    #[config(default = 4)]
    pub visual_samples: usize,
}

impl RunConfig {
    /// The paper's pretraining settings (200k steps, batch 16, 384x512
    /// crops, max LR 2e-4) with a 192-pixel disparity range.
    pub fn paper() -> Self {
        RunConfig::new(
            TrainerConfig::new(LossConfig::new(), OneCycleConfig::new(2e-4, 200_000)),
            NetworkConfig::new(),
            AugmentConfig::default(),
            DataConfig::new(),
        )
    }

    /// Number of optimiser steps of the run.
    pub fn steps(&self) -> usize {
        self.trainer.lr.total_steps
    }

    /// The configuration as a JSON value.
    pub fn to_json(&self) -> Result<Value, TrainError> {
        serde_json::to_value(self).map_err(|e| TrainError::Config(e.to_string()))
    }

    /// Reads a configuration file (JSON, any subset of the keys) for
    /// [`RunConfig::layered`]; errors name the file.
    pub fn read_file(path: &std::path::Path) -> Result<Value, TrainError> {
        let text =
            mbs_core::regular::read_text(path).map_err(|e| TrainError::data(path, e.reason()))?;
        serde_json::from_str(&text).map_err(|e| TrainError::data(path, format!("not JSON: {e}")))
    }

    /// The paper's defaults, then the backbone's own
    /// ([`RunConfig::backbone_defaults`]), overlaid with `file` (any subset
    /// of the keys) and then with each `key.path=value` override, checked
    /// against the schema and the ranges. The backbone is the one `file` and
    /// the overrides pick.
    pub fn layered(file: Option<&Value>, overrides: &[String]) -> Result<Self, TrainError> {
        let mut chosen = Self::paper().to_json()?;
        overlay_users(&mut chosen, file, overrides)?;
        let Ok(backbone) = serde_json::from_value(chosen["network"]["backbone"].clone()) else {
            // Not a backbone: the schema check names the problem.
            return Self::from_document(&chosen);
        };
        let mut document = Self::paper().to_json()?;
        layered::apply_overrides(&mut document, &Self::backbone_defaults(backbone))
            .map_err(TrainError::Config)?;
        overlay_users(&mut document, file, overrides)?;
        Self::from_document(&document)
    }

    /// The configuration of a run resumed from a checkpoint trained with
    /// `saved`: `saved` overlaid with `file` and the overrides, as
    /// [`RunConfig::layered`] overlays the defaults. A setting the user
    /// does not give keeps the checkpoint's value, so a run resumes as it
    /// was trained even after a default changed; one the user gives that
    /// differs is refused when the run opens.
    pub fn resumed(
        saved: &RunConfig,
        file: Option<&Value>,
        overrides: &[String],
    ) -> Result<Self, TrainError> {
        let mut document = saved.to_json()?;
        overlay_users(&mut document, file, overrides)?;
        Self::from_document(&document)
    }

    /// The settings whose default depends on the backbone, as `key=value`
    /// overrides under the user's own. RAFT-Stereo and IGEV-Stereo, whose
    /// iterative updates can take the disparities anywhere, train from
    /// random weights with the S3 safeguards (docs/training.md, "S3 from random
    /// weights"): the geometry term off for the first 30 % of the run and
    /// rising over the next half, its target matched to the student's
    /// scale, a photometric gradient outside the student's mask, and the
    /// learning rate warmed up over 20 % of the run. IGEV-Stereo, whose
    /// first disparities lie in the middle of its cost volume, where many
    /// warps leave the image, adds the view term. The compact network,
    /// whose soft-argmin stays in its range, keeps the paper's loss and
    /// schedule, with which it learns best.
    pub fn backbone_defaults(backbone: BackboneKind) -> Vec<String> {
        let iterative = [
            "trainer.geometry_start=0.3",
            "trainer.geometry_warmup=0.5",
            "trainer.loss.geometry_scale_match=true",
            "trainer.loss.outside_mask_weight=0.1",
            "trainer.lr.pct_start=0.2",
        ];
        let settings: Vec<&str> = match backbone {
            BackboneKind::Compact => vec!["trainer.geometry_start=0", "trainer.geometry_warmup=0"],
            BackboneKind::RaftStereo => iterative.to_vec(),
            BackboneKind::Igev => [&iterative[..], &["trainer.loss.view_weight=0.1"]].concat(),
        };
        settings.into_iter().map(str::to_string).collect()
    }

    /// A complete configuration document (as saved in a checkpoint),
    /// checked against the schema and the ranges. A key added since the
    /// document was written takes the value runs had before it existed
    /// (the S3 safeguards were all off), so an older checkpoint resumes as
    /// it was trained.
    pub fn from_document(document: &Value) -> Result<Self, TrainError> {
        let mut document = document.clone();
        for (path, value) in legacy_values() {
            let keys: Vec<&str> = path.split('.').collect();
            let Some((key, parents)) = keys.split_last() else {
                continue;
            };
            let parent = parents
                .iter()
                .try_fold(&mut document, |node, key| node.get_mut(*key));
            if let Some(Value::Object(section)) = parent {
                section.entry(*key).or_insert(value);
            }
        }
        check_schema(&document).map_err(TrainError::Config)?;
        let config: RunConfig =
            serde_json::from_value(document).map_err(|e| TrainError::Config(e.to_string()))?;
        config.validate()?;
        Ok(config)
    }

    /// Checks every part's ranges.
    pub fn validate(&self) -> Result<(), TrainError> {
        self.augment.validate()?;
        self.data.validate()?;
        self.trainer.validate()?;
        for (name, value) in [
            ("log_every", self.log_every),
            ("val_every", self.val_every),
            ("checkpoint_every", self.checkpoint_every),
            ("keep_checkpoints", self.keep_checkpoints),
        ] {
            ranges::at_least_one(name, value)?;
        }
        Ok(self.network.validate()?)
    }
}

/// Overlays `document` with the user's `file` (any subset of the keys,
/// checked against the schema first) and then with each `key.path=value`
/// override.
fn overlay_users(
    document: &mut Value,
    file: Option<&Value>,
    overrides: &[String],
) -> Result<(), TrainError> {
    if let Some(file) = file {
        layered::merge(document, file);
        // Checked before the overrides, which could hide a wrong value.
        check_schema(document)
            .map_err(|issues| TrainError::Config(format!("the configuration file: {issues}")))?;
    }
    layered::apply_overrides(document, overrides).map_err(TrainError::Config)
}

/// The settings added after the first checkpoints were written, with what
/// runs did before them: the S3 safeguards (docs/training.md, "S3 from random
/// weights"), all off before they existed, the teacher's iterations, and
/// the photometric term's reduction.
fn legacy_values() -> [(&'static str, Value); 9] {
    [
        ("trainer.initial_weight", Value::Null),
        ("trainer.teacher_test_iters", Value::from(true)),
        ("trainer.geometry_start", Value::from(0.0)),
        ("trainer.geometry_warmup", Value::from(0.0)),
        ("trainer.loss.range_weight", Value::from(0.0)),
        ("trainer.loss.out_of_view_invalid", Value::from(false)),
        ("trainer.loss.photometric_mask_mean", Value::from(false)),
        ("trainer.loss.outside_mask_weight", Value::from(0.0)),
        ("trainer.loss.view_weight", Value::from(0.0)),
    ]
}

/// `document`'s schema issues, each with its JSON pointer, joined.
fn check_schema(document: &Value) -> Result<(), String> {
    let issues: Vec<String> = SCHEMA
        .issues(document)
        .into_iter()
        .map(|issue| {
            if issue.pointer.is_empty() {
                issue.message
            } else {
                format!("{}: {}", issue.pointer, issue.message)
            }
        })
        .collect();
    match issues.is_empty() {
        true => Ok(()),
        false => Err(issues.join("; ")),
    }
}

/// The schema every configuration document is checked against.
static SCHEMA: EmbeddedSchema = EmbeddedSchema::new(TRAIN_CONFIG_SCHEMA);

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// Every key path of a JSON object, dotted.
    fn keys(value: &Value, prefix: &str, out: &mut Vec<String>) {
        if let Value::Object(map) = value {
            for (key, child) in map {
                let path = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                out.push(path.clone());
                keys(child, &path, out);
            }
        }
    }

    /// Every property the schema declares, with its dotted path.
    fn schema_properties<'a>(schema: &'a Value, prefix: &str, out: &mut Vec<(String, &'a Value)>) {
        if let Some(Value::Object(properties)) = schema.get("properties") {
            for (key, child) in properties {
                let path = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                out.push((path.clone(), child));
                schema_properties(child, &path, out);
            }
        }
    }

    #[test]
    fn the_schema_describes_exactly_the_configs_keys() {
        let mut config_keys = Vec::new();
        keys(
            &RunConfig::paper().to_json().expect("serialises"),
            "",
            &mut config_keys,
        );
        let schema: Value = serde_json::from_str(TRAIN_CONFIG_SCHEMA).expect("schema is JSON");
        let mut properties = Vec::new();
        schema_properties(&schema, "", &mut properties);
        let mut declared: Vec<String> = properties.into_iter().map(|(path, _)| path).collect();
        config_keys.sort();
        declared.sort();
        assert_eq!(config_keys, declared);
    }

    #[test]
    fn defaults_are_the_papers_and_valid() {
        let config = RunConfig::layered(None, &[]).expect("defaults are valid");
        assert_eq!(config.steps(), 200_000);
        assert_eq!(config.trainer.lr.max_lr, 2e-4);
        assert_eq!(config.trainer.loss.tau, 0.1);
        assert_eq!(config.trainer.loss.omega, 2.0);
        assert_eq!(config.trainer.loss.lambda_p, 10.0);
        assert_eq!(config.data.batch_size, 16);
        assert_eq!(
            (config.data.crop_height, config.data.crop_width),
            (384, 512)
        );
    }

    #[test]
    fn the_code_bounds_every_size_as_the_schema_does() {
        // Checked without the schema, as a network's --set in predict is.
        let schema: Value = serde_json::from_str(TRAIN_CONFIG_SCHEMA).expect("schema is JSON");
        let mut properties = Vec::new();
        schema_properties(&schema, "", &mut properties);
        // (path, maximum, the step between allowed values)
        let sizes: Vec<(String, u64, u64)> = properties
            .into_iter()
            .filter(|(path, _)| path.starts_with("network.") || path.starts_with("data."))
            .filter(|(_, node)| node.get("type").and_then(Value::as_str) == Some("integer"))
            .filter_map(|(path, node)| {
                let step = node.get("multipleOf").and_then(Value::as_u64).unwrap_or(1);
                Some((path, node.get("maximum")?.as_u64()?, step))
            })
            .collect();
        assert!(sizes.len() >= 18, "{sizes:?}");
        for (path, max, step) in sizes {
            let backbone = match path.split('.').nth(1) {
                Some("raft_stereo") => "raft-stereo",
                Some("igev") => "igev",
                _ => "compact",
            };
            // The next allowed value past the maximum: refused by the bound
            // alone, not by the multiple.
            for (value, ok) in [(max, true), (max + step, false)] {
                let mut document = RunConfig::paper().to_json().expect("serialises");
                let keys = |p: &str| p.split('.').map(str::to_owned).collect::<Vec<_>>();
                layered::set_path(&mut document, &keys("network.backbone"), json!(backbone))
                    .expect("a key");
                layered::set_path(&mut document, &keys(&path), json!(value)).expect("a key");
                let config: RunConfig = serde_json::from_value(document).expect("well typed");
                assert_eq!(config.validate().is_ok(), ok, "{path} = {value}");
            }
        }
    }

    #[test]
    fn a_document_from_before_the_safeguards_keeps_them_off() {
        let overrides = ["network.backbone=raft-stereo".to_string()];
        let mut document = RunConfig::layered(None, &overrides)
            .expect("valid")
            .to_json()
            .expect("serialises");
        let trainer = document["trainer"].as_object_mut().expect("an object");
        trainer.remove("geometry_start");
        trainer.remove("geometry_warmup");
        trainer.remove("teacher_test_iters");
        trainer.remove("initial_weight");
        let loss = trainer["loss"].as_object_mut().expect("an object");
        loss.remove("range_weight");
        loss.remove("out_of_view_invalid");
        loss.remove("photometric_mask_mean");
        loss.remove("outside_mask_weight");
        loss.remove("view_weight");
        let old = RunConfig::from_document(&document).expect("valid");
        assert_eq!(
            (old.trainer.geometry_start, old.trainer.geometry_warmup),
            (Some(0.0), Some(0.0))
        );
        assert_eq!(old.trainer.loss.range_weight, 0.0);
        assert!(!old.trainer.loss.out_of_view_invalid);
        assert!(!old.trainer.loss.photometric_mask_mean);
        assert_eq!(old.trainer.loss.outside_mask_weight, 0.0);
        assert_eq!(old.trainer.loss.view_weight, 0.0);
        assert!(old.trainer.teacher_test_iters);
        assert_eq!(old.trainer.initial_weight, None);
        // A document that has the keys keeps them.
        let new = RunConfig::layered(None, &overrides).expect("valid");
        assert_eq!(new.trainer.geometry_start, Some(0.3));
        assert!(new.trainer.loss.out_of_view_invalid);
    }

    #[test]
    fn backbone_defaults_lie_under_the_users_settings() {
        let trainer = |overrides: &[&str]| {
            let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
            RunConfig::layered(None, &overrides).expect("valid").trainer
        };
        let compact = trainer(&[]);
        assert_eq!(
            (compact.geometry_start, compact.geometry_warmup),
            (Some(0.0), Some(0.0)),
            "compact keeps the paper's loss"
        );
        assert!(!compact.loss.geometry_scale_match);
        assert_eq!(compact.loss.outside_mask_weight, 0.0);
        assert_eq!(compact.loss.view_weight, 0.0);
        assert_eq!(compact.lr.pct_start, 0.01);
        for backbone in ["raft-stereo", "igev"] {
            let iterative = trainer(&[&format!("network.backbone={backbone}")]);
            assert_eq!(
                (iterative.geometry_start, iterative.geometry_warmup),
                (Some(0.3), Some(0.5))
            );
            assert!(iterative.loss.geometry_scale_match);
            assert_eq!(iterative.loss.outside_mask_weight, 0.1);
            let view_weight = if backbone == "igev" { 0.1 } else { 0.0 };
            assert_eq!(iterative.loss.view_weight, view_weight, "{backbone}");
            assert_eq!(iterative.lr.pct_start, 0.2);
        }
        // The user's settings win, from a file as from an override.
        let set = trainer(&[
            "network.backbone=igev",
            "trainer.geometry_warmup=0.2",
            "trainer.loss.outside_mask_weight=0",
        ]);
        assert_eq!(
            (set.geometry_start, set.geometry_warmup),
            (Some(0.3), Some(0.2))
        );
        assert_eq!(set.loss.outside_mask_weight, 0.0);
        let file =
            json!({"network": {"backbone": "raft-stereo"}, "trainer": {"lr": {"pct_start": 0.05}}});
        let from_file = RunConfig::layered(Some(&file), &[]).expect("valid").trainer;
        assert_eq!(from_file.lr.pct_start, 0.05);
        assert!(from_file.loss.geometry_scale_match);
        let err = RunConfig::layered(None, &["network.backbone=raft".into()])
            .unwrap_err()
            .to_string();
        assert!(err.contains("/network/backbone"), "{err}");
        let err = RunConfig::layered(
            None,
            &[
                "trainer.geometry_start=0.7".into(),
                "trainer.geometry_warmup=0.5".into(),
            ],
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("would not reach its full weight"), "{err}");
    }

    #[test]
    fn files_and_overrides_layer_on_the_defaults() {
        let file = json!({"trainer": {"loss": {"omega": 3.0}}, "data": {"batch_size": 2}});
        let config = RunConfig::layered(
            Some(&file),
            &[
                "trainer.lr.total_steps=50".into(),
                "trainer.loss.geometry=false".into(),
                "data.val_pairs=[[1,2],[1,0]]".into(),
                "data.val_split=train".into(),
            ],
        )
        .expect("valid");
        assert_eq!(config.trainer.loss.omega, 3.0);
        assert!(!config.trainer.loss.geometry);
        assert!(
            config.trainer.loss.photometric,
            "untouched keys keep their default"
        );
        assert_eq!(config.data.batch_size, 2);
        assert_eq!(config.steps(), 50);
        assert_eq!(config.data.val_pairs, vec![[1, 2], [1, 0]]);
        assert_eq!(config.data.val_split, Some(mbs_dataset::Split::Train));
        assert!(
            RunConfig::layered(None, &["data.val_split=holdout".into()]).is_err(),
            "not a split"
        );
    }

    #[test]
    fn bad_values_are_named() {
        let err = |overrides: &[&str]| {
            let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
            RunConfig::layered(None, &overrides)
                .expect_err("must be refused")
                .to_string()
        };
        assert!(err(&["trainer.loss.omgea=3"]).contains("unknown key `trainer.loss.omgea`"));
        assert!(err(&["data.batch_size=-1"]).contains("/data/batch_size"));
        assert!(err(&["trainer.loss.tau=fast"]).contains("/trainer/loss/tau"));
        assert!(err(&["seed"]).contains("not KEY=VALUE"));
        assert!(err(&["trainer.loss.ssim_window=4"]).contains("ssim_window"));
        let file = json!({"trainer": {"loss": {"typo": 1}}});
        let message = RunConfig::layered(Some(&file), &[])
            .expect_err("unknown key in a file")
            .to_string();
        assert!(message.contains("typo"), "{message}");
    }
}
