//! The public stereo benchmarks whose folders mbs reads as their downloads
//! unpack. How each is scored (its threshold, the paper's Table 4's
//! included) is `mbs_core::metrics::Protocol`'s business.

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
    fn each_benchmark_has_its_name() {
        let names: Vec<String> = Benchmark::ALL.iter().map(|b| b.to_string()).collect();
        assert_eq!(
            names,
            ["KITTI", "Middlebury", "ETH3D", "DrivingStereo", "SceneFlow"]
        );
    }
}
