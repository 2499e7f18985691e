//! What a training run will need in memory, estimated from its settings
//! before anything is allocated, and the machine's memory to compare it
//! with.
//!
//! The estimate scales peaks measured on this project's CPU backend
//! (BENCHMARKS.md, "S3 training step"): per batch item and crop pixel,
//! 47.8 kB for RAFT-Stereo (hidden 128, 16 training iterations), 54.0 kB
//! for IGEV-Stereo (hidden 128, 22 iterations) and 0.54 kB for the compact
//! network (128 px of disparity), each taken as the slope between batch 1
//! and batch 2 (or two crops). The iterative networks' activations grow
//! with their hidden width and training iterations, the compact network's
//! with its disparity range; parameters (with their gradient, Adam's two
//! moments and the teacher: 5 copies in f32) grow with the square of the
//! hidden width. It is meant to be right within a factor of two, which is
//! why a run is refused only well past the machine's memory.

use std::fs;

use mbs_nets::device::DeviceName;
use mbs_nets::{BackboneKind, NetworkConfig};

use crate::config::RunConfig;
use crate::error::TrainError;

/// Bytes per batch item and crop pixel at the reference settings below.
const RAFT_STEREO_BYTES_PER_PIXEL: f64 = 47.8e3;
const IGEV_BYTES_PER_PIXEL: f64 = 54.0e3;
const COMPACT_BYTES_PER_PIXEL: f64 = 0.54e3;
/// The reference settings of those figures.
const REFERENCE_HIDDEN: f64 = 128.0;
const RAFT_STEREO_REFERENCE_ITERS: f64 = 16.0;
const IGEV_REFERENCE_ITERS: f64 = 22.0;
const COMPACT_REFERENCE_DISPARITY: f64 = 128.0;
/// Parameters at the reference width (the official networks).
const RAFT_STEREO_PARAMETERS: f64 = 11.1e6;
const IGEV_PARAMETERS: f64 = 12.6e6;
const COMPACT_PARAMETERS: f64 = 45e3;
/// Student, its gradient, Adam's two moments and the teacher, in f32.
const BYTES_PER_PARAMETER: f64 = 5.0 * 4.0;

/// A training run's estimated memory on the CPU, in bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MemoryEstimate {
    /// The networks' parameters, gradients and optimiser state.
    pub networks: f64,
    /// One step's activations for `items` batch items.
    pub activations: f64,
}

impl MemoryEstimate {
    /// The estimate for `items` batch items of `config`'s crop (the share
    /// of the batch that one CPU device computes).
    pub fn of(config: &RunConfig, items: usize) -> Self {
        let pixels = (config.data.crop_height * config.data.crop_width) as f64;
        let (per_pixel, parameters) = per_pixel_and_parameters(&config.network);
        Self {
            networks: parameters * BYTES_PER_PARAMETER,
            activations: per_pixel * pixels * items as f64,
        }
    }

    /// Networks and activations together.
    pub fn total(&self) -> f64 {
        self.networks + self.activations
    }
}

/// Activation bytes per item and pixel, and the parameter count.
fn per_pixel_and_parameters(network: &NetworkConfig) -> (f64, f64) {
    match network.backbone {
        BackboneKind::Compact => {
            let range = network.max_disparity as f64 / COMPACT_REFERENCE_DISPARITY;
            (COMPACT_BYTES_PER_PIXEL * range.max(1.0), COMPACT_PARAMETERS)
        }
        BackboneKind::RaftStereo => iterative(
            [RAFT_STEREO_BYTES_PER_PIXEL, RAFT_STEREO_PARAMETERS],
            network.raft_stereo.hidden_dim,
            network.raft_stereo.train_iters as f64 / RAFT_STEREO_REFERENCE_ITERS,
        ),
        BackboneKind::Igev => iterative(
            [IGEV_BYTES_PER_PIXEL, IGEV_PARAMETERS],
            network.igev.hidden_dim,
            network.igev.train_iters as f64 / IGEV_REFERENCE_ITERS,
        ),
    }
}

/// An iterative network's figures at the reference width scaled to
/// `hidden` channels and `iters` times the reference iterations:
/// activations linear in both, parameters quadratic in the width.
fn iterative([per_pixel, parameters]: [f64; 2], hidden: usize, iters: f64) -> (f64, f64) {
    let width = hidden as f64 / REFERENCE_HIDDEN;
    (
        per_pixel * width * iters,
        parameters * width.max(width * width),
    )
}

/// The machine's memory, from `/proc/meminfo`, in bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MachineMemory {
    /// RAM and swap together.
    pub total: f64,
    /// What a new allocation can have now (`MemAvailable` and free swap).
    pub available: f64,
}

impl MachineMemory {
    /// Reads `/proc/meminfo`; `None` where it cannot be read (not Linux).
    pub fn read() -> Option<Self> {
        Self::parse(&fs::read_to_string("/proc/meminfo").ok()?)
    }

    /// Parses the text of `/proc/meminfo`.
    pub fn parse(meminfo: &str) -> Option<Self> {
        let field = |name: &str| {
            meminfo.lines().find_map(|line| {
                let value = line.strip_prefix(name)?.strip_prefix(':')?;
                let kib: f64 = value.trim().strip_suffix("kB")?.trim().parse().ok()?;
                Some(kib * 1024.0)
            })
        };
        let swap_total = field("SwapTotal").unwrap_or(0.0);
        let swap_free = field("SwapFree").unwrap_or(0.0);
        Some(Self {
            total: field("MemTotal")? + swap_total,
            available: field("MemAvailable")? + swap_free,
        })
    }
}

/// How an estimate compares with the machine's memory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MemoryVerdict {
    /// It fits in what is available now.
    Fits,
    /// It may not fit: more than is available now.
    Tight,
    /// More than twice the machine's RAM and swap: it cannot run.
    TooLarge,
}

impl MemoryVerdict {
    /// `estimate` against `machine`.
    pub fn of(estimate: &MemoryEstimate, machine: &MachineMemory) -> Self {
        let total = estimate.total();
        if total > 2.0 * machine.total {
            Self::TooLarge
        } else if total > machine.available {
            Self::Tight
        } else {
            Self::Fits
        }
    }
}

/// Checks a run on `devices` against this machine's memory before
/// anything is allocated: the batch items that the CPU devices among them
/// compute (GPU memory is not checked). An error when the estimate is more
/// than twice the machine's RAM and swap; a warning to show when it is
/// more than is available now; nothing where `/proc/meminfo` cannot be
/// read.
pub fn check(config: &RunConfig, devices: &[DeviceName]) -> Result<Option<String>, TrainError> {
    let on_cpu = devices.iter().filter(|d| **d == DeviceName::Cpu).count();
    let items = (config.data.batch_size * on_cpu).div_ceil(devices.len().max(1));
    if items == 0 {
        return Ok(None);
    }
    let Some(machine) = MachineMemory::read() else {
        return Ok(None);
    };
    let estimate = MemoryEstimate::of(config, items);
    let need = format!(
        "a training step of {items} batch item(s) of {}x{} on the CPU needs about {} \
         ({} for the networks and the optimiser, {} for activations)",
        config.data.crop_height,
        config.data.crop_width,
        gib(estimate.total()),
        gib(estimate.networks),
        gib(estimate.activations),
    );
    let lower = "lower --batch-size or --crop, or narrow the network";
    match MemoryVerdict::of(&estimate, &machine) {
        MemoryVerdict::Fits => Ok(None),
        MemoryVerdict::Tight => Ok(Some(format!(
            "{need}, more than the {} available now; {lower}",
            gib(machine.available)
        ))),
        MemoryVerdict::TooLarge => Err(TrainError::Config(format!(
            "{need}, more than twice this machine's {} of memory and swap; {lower}",
            gib(machine.total)
        ))),
    }
}

/// Bytes as GiB with one decimal, for messages.
pub fn gib(bytes: f64) -> String {
    format!("{:.1} GiB", bytes / (1u64 << 30) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(backbone: BackboneKind, batch: usize, height: usize, width: usize) -> RunConfig {
        let mut config = RunConfig::paper();
        config.network.backbone = backbone;
        config.data.batch_size = batch;
        config.data.crop_height = height;
        config.data.crop_width = width;
        config
    }

    /// The estimate against the peaks measured with `step_time` (batch 2,
    /// 384x512, default networks: RAFT-Stereo 18215 MiB, IGEV-Stereo
    /// 20749 MiB) and the compact network's S3 step (batch 2, 256x512,
    /// 128 px: 225 MiB, of which about 90 MiB are the process).
    #[test]
    fn estimates_meet_the_measured_peaks() {
        let mib = |bytes: f64| bytes / (1u64 << 20) as f64;
        for (backbone, batch, height, width, measured) in [
            (BackboneKind::RaftStereo, 2, 384, 512, 18215.0),
            (BackboneKind::RaftStereo, 1, 384, 512, 9255.0),
            (BackboneKind::Igev, 2, 384, 512, 20749.0),
            (BackboneKind::Igev, 1, 384, 512, 10633.0),
            (BackboneKind::Compact, 2, 256, 512, 225.0 - 90.0),
        ] {
            let mut config = run(backbone, batch, height, width);
            config.network.max_disparity = 128;
            let estimate = mib(MemoryEstimate::of(&config, batch).total());
            assert!(
                (estimate / measured - 1.0).abs() < 0.1,
                "{backbone:?} batch {batch}: {estimate:.0} MiB estimated, {measured} measured"
            );
        }
    }

    #[test]
    fn wider_and_longer_networks_need_more() {
        let base = run(BackboneKind::RaftStereo, 1, 256, 256);
        let mut wide = base.clone();
        wide.network.raft_stereo.hidden_dim = 1024;
        let mut long = base.clone();
        long.network.raft_stereo.train_iters = 64;
        let of = |config: &RunConfig| MemoryEstimate::of(config, 1);
        assert!((of(&wide).activations / of(&base).activations - 8.0).abs() < 1e-9);
        assert!((of(&wide).networks / of(&base).networks - 64.0).abs() < 1e-9);
        assert!((of(&long).activations / of(&base).activations - 4.0).abs() < 1e-9);
    }

    #[test]
    fn meminfo_is_read_and_estimates_are_judged() {
        let meminfo = "MemTotal:       24000000 kB\nMemFree:         1000 kB\n\
                       MemAvailable:   20000000 kB\nSwapTotal:      1000000 kB\n\
                       SwapFree:        500000 kB\n";
        let machine = MachineMemory::parse(meminfo).expect("parses");
        assert_eq!(machine.total, 25_000_000.0 * 1024.0);
        assert_eq!(machine.available, 20_500_000.0 * 1024.0);
        assert_eq!(MachineMemory::parse("MemTotal: 1 kB\n"), None);
        let needing = |bytes: f64| MemoryEstimate {
            networks: 0.0,
            activations: bytes,
        };
        let verdict = |bytes| MemoryVerdict::of(&needing(bytes), &machine);
        assert_eq!(verdict(1e9), MemoryVerdict::Fits);
        assert_eq!(verdict(22e9), MemoryVerdict::Tight);
        assert_eq!(verdict(60e9), MemoryVerdict::TooLarge);
    }
}
