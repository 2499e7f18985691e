//! A gradient reduction written outside mbs-train plugs into a run through
//! `Launch::reduction` without editing the crate: one that records what it
//! sums and delegates to the host all-reduce trains a run whose every
//! step's loss and gradient norm, and whose last validation, equal those
//! of the same run with the default reduction, and it saw every step's
//! gradients with their length.
#![allow(clippy::unwrap_used)]

use std::cell::RefCell;
use std::path::Path;
use std::rc::Rc;
use std::sync::atomic::AtomicBool;

use burn::optim::GradientsParams;
use burn::tensor::Device;
use mbs_nets::StereoNetwork;
use mbs_train::RunConfig;
use mbs_train::distributed::Collective;
use mbs_train::error::TrainError;
use mbs_train::launch::{Beginning, Ended, Launch};
use mbs_train::run::{Quiet, read_log};
use mbs_train::step::{
    GradientReduction, HostAllReduce, InProcessSum, LocalGradients, ShareGradients,
};

mod common;

/// A job of one process: every collective call is this process's own.
struct Alone;

impl Collective for Alone {
    fn rank(&self) -> usize {
        0
    }
    fn size(&self) -> usize {
        1
    }
    fn local_rank(&self) -> usize {
        0
    }
    fn abort(&self, code: i32) -> ! {
        panic!("aborted with {code}")
    }
    fn sum(&self, values: Vec<f32>) -> Vec<f32> {
        values
    }
    fn gather(&self, bytes: &[u8]) -> Vec<Vec<u8>> {
        vec![bytes.to_vec()]
    }
}

/// Records the length of each local sum, then delegates to the host
/// all-reduce; `on_device`, it keeps the sum on the device instead, as a
/// device-side collective would (over one process, the sum is itself).
struct Recording {
    inner: HostAllReduce,
    on_device: bool,
    lengths: RefCell<Vec<usize>>,
}

impl GradientReduction<StereoNetwork> for Recording {
    fn processes(&self) -> Option<&dyn Collective> {
        GradientReduction::<StereoNetwork>::processes(&self.inner)
    }
    fn local_sum(
        &self,
        student: &StereoNetwork,
        shares: Vec<ShareGradients<StereoNetwork>>,
        home: &Device,
    ) -> Result<LocalGradients, TrainError> {
        let local = match self.on_device {
            true => InProcessSum.local_sum(student, shares, home)?,
            false => self.inner.local_sum(student, shares, home)?,
        };
        assert_eq!(
            matches!(local, LocalGradients::OnDevice { .. }),
            self.on_device
        );
        self.lengths.borrow_mut().push(local.length());
        Ok(local)
    }
    fn sum_over_processes(
        &self,
        student: &StereoNetwork,
        local: LocalGradients,
    ) -> Result<GradientsParams, TrainError> {
        match self.on_device {
            true => Ok(local.into_device()),
            false => self.inner.sum_over_processes(student, local),
        }
    }
}

/// Trains 3 steps of a small compact network into `out` on `processes`
/// with `reduction`, and returns each step's loss and gradient norm and
/// the last validation's figures.
fn train(
    manifest: &Path,
    out: &Path,
    processes: Rc<dyn Collective>,
    reduction: Option<Rc<dyn GradientReduction<StereoNetwork>>>,
) -> (Vec<(f64, f64)>, serde_json::Value) {
    let overrides: Vec<String> = [
        "network.backbone=compact",
        "network.max_disparity=32",
        "trainer.lr.total_steps=3",
        "data.batch_size=2",
        "data.crop_height=32",
        "data.crop_width=64",
        "val_every=3",
        "checkpoint_every=3",
        "seed=3",
        "log_every=1",
    ]
    .map(String::from)
    .to_vec();
    let launched = Launch {
        manifest,
        out,
        config: RunConfig::layered(None, &overrides).unwrap(),
        devices: &"cpu".parse().unwrap(),
        processes: Some(processes),
        beginning: Beginning::default(),
        reduction,
    }
    .open()
    .unwrap();
    let ended = launched.train(&mut Quiet, &AtomicBool::new(false)).unwrap();
    assert!(matches!(ended, Ended::Finished { .. }), "{ended:?}");
    let steps = read_log(&out.join("train.jsonl"))
        .unwrap()
        .iter()
        .map(|line| {
            (
                line["loss"].as_f64().unwrap(),
                line["grad_norm"].as_f64().unwrap(),
            )
        })
        .collect();
    let validation = read_log(&out.join("val.jsonl")).unwrap().pop().unwrap();
    (steps, validation["ALL"].clone())
}

#[test]
fn a_reduction_from_outside_the_crate_sums_a_run_as_the_default_does() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = common::synthesise_like_the_cli(&dir.path().join("data"), 13);
    let processes: Rc<dyn Collective> = Rc::new(Alone);
    let default = train(
        &manifest,
        &dir.path().join("default"),
        Rc::clone(&processes),
        None,
    );
    assert_eq!(default.0.len(), 3);
    let mut lengths = Vec::new();
    for on_device in [false, true] {
        let recording = Rc::new(Recording {
            inner: HostAllReduce::new(Rc::clone(&processes)),
            on_device,
            lengths: RefCell::new(Vec::new()),
        });
        let reduction: Rc<dyn GradientReduction<StereoNetwork>> = recording.clone();
        let out = dir.path().join(format!("plugged-{on_device}"));
        let plugged = train(&manifest, &out, Rc::clone(&processes), Some(reduction));
        assert_eq!(plugged, default, "on the device: {on_device}");
        lengths.extend(recording.lengths.take());
    }
    // Both forms count the same gradient values at each of the 3 steps.
    assert_eq!(lengths.len(), 6, "{lengths:?}");
    assert!(
        lengths.iter().all(|&n| n == lengths[0] && n > 1000),
        "{lengths:?}"
    );
}
