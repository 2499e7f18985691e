//! The public stereo benchmarks whose folders mbs reads as their downloads
//! unpack, with the protocol each is customarily scored by (the S3
//! paper's Table 4): Out-3 on KITTI and DrivingStereo, Out-2 on
//! Middlebury, Out-1 on ETH3D, EPE and Out-1 on SceneFlow.

use std::fmt;

/// A benchmark with a folder layout of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Benchmark {
    /// KITTI 2015 or 2012 ([`crate::kitti`]).
    Kitti,
    /// Middlebury 2014 / MiddEval3 ([`crate::two_view`]).
    Middlebury,
    /// ETH3D two-view ([`crate::two_view`]).
    Eth3d,
    /// DrivingStereo's weather subsets ([`crate::driving_stereo`]).
    DrivingStereo,
    /// SceneFlow: FlyingThings3D, Driving, Monkaa ([`crate::scene_flow`]).
    SceneFlow,
}

impl Benchmark {
    /// Every benchmark, in the order tables list them.
    pub const ALL: [Benchmark; 5] = [
        Benchmark::Kitti,
        Benchmark::Middlebury,
        Benchmark::Eth3d,
        Benchmark::DrivingStereo,
        Benchmark::SceneFlow,
    ];

    /// The benchmark's name, as tables and messages spell it.
    pub fn name(self) -> &'static str {
        match self {
            Benchmark::Kitti => "KITTI",
            Benchmark::Middlebury => "Middlebury",
            Benchmark::Eth3d => "ETH3D",
            Benchmark::DrivingStereo => "DrivingStereo",
            Benchmark::SceneFlow => "SceneFlow",
        }
    }

    /// The Out-x threshold (pixels) the benchmark is customarily reported
    /// with: the share of valid pixels whose error exceeds it.
    pub fn customary_threshold(self) -> f32 {
        match self {
            Benchmark::Kitti | Benchmark::DrivingStereo => 3.0,
            Benchmark::Middlebury => 2.0,
            Benchmark::Eth3d | Benchmark::SceneFlow => 1.0,
        }
    }
}

impl fmt::Display for Benchmark {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_benchmark_has_the_papers_metric() {
        let thresholds: Vec<(&str, f32)> = Benchmark::ALL
            .iter()
            .map(|b| (b.name(), b.customary_threshold()))
            .collect();
        assert_eq!(
            thresholds,
            [
                ("KITTI", 3.0),
                ("Middlebury", 2.0),
                ("ETH3D", 1.0),
                ("DrivingStereo", 3.0),
                ("SceneFlow", 1.0)
            ]
        );
    }
}
