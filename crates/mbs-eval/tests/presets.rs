//! Every preset scored by the library on real data (tests/presets/fixture.rs:
//! Teddy laid out as each benchmark's folder, with predictions that have
//! errors of every size, holes and values beyond the image): its figures
//! equal, to 1e-6, a computation written from its project's code (not from
//! the library's); every two presets give different figures on the data
//! they share; a preset without rules for a dataset refuses it, naming the
//! data it has rules for. The binary's flags and output are mbs-tool's
//! tests/protocols.rs.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

#[path = "presets/fixture.rs"]
mod fixture;

use std::collections::BTreeMap;
use std::path::Path;

use fixture::*;
use mbs_core::FloatImage;
use mbs_dataset::pairs::PairSource;
use mbs_eval::{EvalError, Protocol, SourceScores, rules_for, score_predictions};
use serde_json::Value;

/// `layout`'s folder as a source of pairs (its flag names its benchmark).
fn source(layout: &Layout) -> PairSource {
    PairSource::Benchmark {
        benchmark: layout.flag.trim_start_matches("--").parse().unwrap(),
        dir: layout.dir.clone(),
    }
}

/// The predictions in `predictions` of `layout`'s pairs scored under
/// `preset` at its own thresholds (Out-1, 2, 3 under pixels), as `eval
/// PREDICTIONS FLAG DIR --protocol PRESET` scores them; the refusal when
/// the preset has no rules for the layout's data.
fn score(layout: &Layout, predictions: &Path, preset: &str) -> Result<SourceScores, EvalError> {
    let protocol: Protocol = preset.parse().unwrap();
    let source = source(layout);
    let rules = rules_for(protocol, source.dataset(), &[])?;
    score_predictions(&source, predictions, None, &rules, &|_| {})
}

/// Every preset on every layout: the figures computed here, to 1e-6, or
/// a refusal naming the data the preset has rules for; then every two
/// presets differ wherever both have rules.
#[test]
fn every_preset_scores_every_layout_as_its_project() {
    let dir = tempfile::tempdir().unwrap();
    let layouts = [
        kitti_layout(dir.path(), 2015),
        kitti_layout(dir.path(), 2012),
        middlebury_layout(dir.path()),
        eth3d_layout(dir.path()),
        driving_stereo_layout(dir.path()),
        scene_flow_layout(dir.path()),
    ];
    let mut scored: BTreeMap<(&str, &str), Scores> = BTreeMap::new();
    for layout in &layouts {
        for preset in PRESETS {
            let result = score(layout, &layout.predictions, preset);
            let Some(want) = expected(preset, layout) else {
                let error = result.err().unwrap().to_string();
                let refusal = format!("protocol {preset} has no rules for {}", layout.dataset);
                assert!(error.contains(&refusal), "{error}");
                continue;
            };
            let scores = result.unwrap();
            assert!(
                scores.failed.is_empty(),
                "{preset} {}: {:?}",
                layout.dataset,
                scores.failed
            );
            let json: Value = scores.json().unwrap();
            assert_eq!(json["protocol"], preset);
            let got = reported(&json, preset, &want.key);
            assert!(
                agree(&got, &want),
                "{preset} on {}: {got:?} != {want:?}",
                layout.dataset
            );
            scored.insert((preset, layout.dataset), got);
        }
    }
    presets_differ_wherever_both_score(&scored);
}

/// For every two presets, the figures differ on every dataset both score
/// (the headline, its value in a region, the regions, or the EPE). Two
/// presets that share no dataset (kitti, eth3d, middlebury) were each seen
/// refusing the other's data above.
fn presets_differ_wherever_both_score(scored: &BTreeMap<(&str, &str), Scores>) {
    let mut compared = 0;
    for (i, a) in PRESETS.iter().enumerate() {
        for b in &PRESETS[i + 1..] {
            for ((preset, dataset), scores) in scored {
                if preset != a {
                    continue;
                }
                if let Some(other) = scored.get(&(*b, *dataset)) {
                    compared += 1;
                    assert!(
                        !agree(scores, other),
                        "{a} and {b} agree on {dataset}: {scores:?}"
                    );
                }
            }
        }
    }
    // pixels-s3 on 6 datasets, each with raft and igev on 5, raft-igev on 5,
    // kitti with 4 on 2 KITTI folders, eth3d and middlebury with 4 on 1.
    assert_eq!(compared, 6 + 2 * 5 * 2 + 5 + 4 * 2 + 4 + 4);
}

/// The middlebury preset takes a prediction at half the ground truth's
/// size (evaldisp's nearest upsampling times 2, computed here), where the
/// others fail that image, naming its size, and score the rest.
#[test]
fn middlebury_upsamples_a_half_size_prediction_where_others_fail_it() {
    let dir = tempfile::tempdir().unwrap();
    let mut layout = middlebury_layout(dir.path());
    let half = &mut layout.frames[1];
    let small = FloatImage::from_fn(WIDTH / 2, HEIGHT / 2, |x, y| {
        image::Luma([half.gt.get_pixel(2 * x, 2 * y).0[0] / 2.0])
    });
    half.pred = predicted(&small, 7);
    let predictions = dir.path().join("pred-half");
    write_predictions(&predictions, &layout.frames);
    let scores = score(&layout, &predictions, "middlebury").unwrap();
    assert!(scores.failed.is_empty(), "{:?}", scores.failed);
    let json: Value = scores.json().unwrap();
    let want = evaldisp(&layout.frames);
    let got = reported(&json, "middlebury", "");
    assert!(agree(&got, &want), "{got:?} != {want:?}");

    let scores = score(&layout, &predictions, "s3").unwrap();
    assert_eq!(scores.failed.len(), 1, "{:?}", scores.failed);
    let (name, error) = &scores.failed[0];
    assert_eq!(name, "Teddy4");
    assert!(
        error
            .to_string()
            .contains("Teddy4.pfm: the prediction is (224, 186)"),
        "{error}"
    );
    let json: Value = scores.json().unwrap();
    assert_eq!(json["images"].as_array().map(Vec::len), Some(1));
}
