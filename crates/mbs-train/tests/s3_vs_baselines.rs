//! End to end on synthetic scenes (paper Table 3, (A) vs (D)): after the
//! same steps from the same seed, the full S3 loss gives a lower Out-3 on
//! OCC and ALL held-out pixels than the untrained network and than
//! photometric + smoothness alone.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::sync::atomic::AtomicBool;

use mbs_eval::Region;
use mbs_train::RunConfig;
use mbs_train::data::validation::ValidationMetrics;
use mbs_train::run::{End, Quiet, TrainingRun};

mod common;

const WIDTH: u32 = 192;
const HEIGHT: u32 = 96;

/// An integer setting from the environment (e.g. `S3_TEST_STEPS`), or `default`.
fn env(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn config(steps: usize, overrides: &[&str]) -> RunConfig {
    let mut all: Vec<String> = vec![
        format!("trainer.lr.total_steps={steps}"),
        "trainer.lr.max_lr=0.002".into(),
        "trainer.lr.pct_start=0.1".into(),
        "trainer.ema_base=0.9".into(),
        "network.max_disparity=64".into(),
        "data.batch_size=4".into(),
        format!("data.crop_height={HEIGHT}"),
        "data.crop_width=160".into(),
        "data.val_samples=0".into(),
        "data.val_pairs=[[0,1],[2,1],[2,3]]".into(),
        "augment.occlusion_min_side=10".into(),
        "augment.occlusion_max_side=30".into(),
        format!("val_every={steps}"),
        format!("checkpoint_every={steps}"),
        "log_every=10".into(),
        "seed=3".into(),
    ];
    all.extend(overrides.iter().map(|s| s.to_string()));
    if let Ok(extra) = std::env::var("S3_TEST_SET") {
        all.extend(extra.split(';').map(str::to_owned));
    }
    RunConfig::layered(None, &all).unwrap()
}

fn train(manifest: &Path, out: &Path, config: RunConfig) -> (ValidationMetrics, ValidationMetrics) {
    let (mut run, _) = TrainingRun::open(manifest, out, config).unwrap();
    let before = run
        .validation()
        .evaluate(run.teacher(), &burn::tensor::Device::flex())
        .unwrap();
    let start = std::time::Instant::now();
    let end = run.run(&mut Quiet, &AtomicBool::new(false)).unwrap();
    println!("trained in {:.1} s", start.elapsed().as_secs_f64());
    let End::Finished { metrics } = end else {
        panic!("not stopped")
    };
    (before, *metrics.unwrap())
}

fn out3(m: &ValidationMetrics, region: Region) -> f64 {
    m.region(region).and_then(|m| m.out(3.0)).unwrap()
}

fn summary(name: &str, m: &ValidationMetrics) {
    println!(
        "{name:<28} EPE ALL {:.2}  Out-3 ALL {:5.2} %  NOC {:5.2} %  OCC {:5.2} %",
        m.all().unwrap().epe.unwrap(),
        out3(m, Region::All),
        out3(m, Region::Noc),
        out3(m, Region::Occ)
    );
}

#[test]
fn full_s3_beats_untrained_and_photometric_smoothness_only() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = common::synthesise(
        &dir.path().join("data"),
        env("S3_TEST_FRAMES", 6),
        WIDTH,
        HEIGHT,
    );
    let steps = env("S3_TEST_STEPS", 400);
    let (untrained, full) = train(&manifest, &dir.path().join("full"), config(steps, &[]));
    let (_, photometric) = train(
        &manifest,
        &dir.path().join("photometric"),
        config(steps, &["trainer.loss.geometry=false"]),
    );
    summary("untrained", &untrained);
    summary("photometric + smoothness", &photometric);
    summary("full S3", &full);
    for region in [Region::All, Region::Occ] {
        assert!(
            out3(&full, region) < 0.8 * out3(&untrained, region),
            "{region:?}: full {} vs untrained {}",
            out3(&full, region),
            out3(&untrained, region)
        );
        assert!(
            out3(&full, region) < out3(&photometric, region),
            "{region:?}: full {} vs photometric {}",
            out3(&full, region),
            out3(&photometric, region)
        );
    }
}
