//! Time of the gradient all-reduce of a data-parallel step: the sum over
//! the ranks of a buffer as long as RAFT-Stereo's and IGEV-Stereo's
//! gradients (their official configurations' parameter counts), as
//! `S3Trainer::step_shared` makes it, plus the flattening of a real
//! set of gradients into that buffer and back.
//!
//! ```bash
//! cargo build --release -p mbs-mpi --example allreduce
//! mpirun -np 2 target/release/examples/allreduce [REPEATS]
//! ```
//!
//! Rank 0 prints one line per network: parameters, megabytes, and the
//! median, min and max milliseconds of the sum and of the round trip.

use std::time::Instant;

use burn::module::Module;
use burn::optim::GradientsParams;
use burn::tensor::Device;
use mbs_mpi::MpiProcesses;
use mbs_nets::{BackboneKind, NetworkConfig};
use mbs_train::distributed::{Collective, FlatGradients};

fn main() {
    let repeats: usize = std::env::args()
        .nth(1)
        .map_or(20, |s| s.parse().expect("REPEATS is a number"));
    let processes = MpiProcesses::join().expect("MPI starts");
    let device = Device::flex();
    for backbone in [BackboneKind::RaftStereo, BackboneKind::Igev] {
        let network = NetworkConfig::new()
            .with_backbone(backbone)
            .init(&device)
            .expect("the official configuration builds");
        let parameters = network.num_params();
        // Each parameter's "gradient" is its value: a real layout to flatten.
        let mut grads = GradientsParams::new();
        network.visit(&mut Register { grads: &mut grads });
        let mut sum_ms = Vec::new();
        let mut round_trip_ms = Vec::new();
        for _ in 0..repeats + 2 {
            let start = Instant::now();
            let mut flat = FlatGradients::gather(&network, &grads).expect("gathered");
            let flattened = start.elapsed();
            processes.gather(&[]); // start the sums together
            let summing = Instant::now();
            flat.sum_over(&processes);
            sum_ms.push(summing.elapsed().as_secs_f64() * 1e3);
            let back = Instant::now();
            drop(flat.into_grads());
            round_trip_ms.push((flattened + back.elapsed()).as_secs_f64() * 1e3);
        }
        // The first two are warm-up.
        let stats = |times: &mut Vec<f64>| {
            let mut kept = times.split_off(2);
            kept.sort_by(f64::total_cmp);
            (kept[kept.len() / 2], kept[0], kept[kept.len() - 1])
        };
        let (median, min, max) = stats(&mut sum_ms);
        let (flat_median, _, _) = stats(&mut round_trip_ms);
        if processes.rank() == 0 {
            println!(
                "{backbone:?}: {parameters} parameters ({:.1} MB of f32 gradients), {} ranks: \
                 all-reduce median {median:.1} ms (min {min:.1}, max {max:.1}, {:.2} GB/s of \
                 buffer), flatten + unflatten {flat_median:.1} ms",
                parameters as f64 * 4e-6,
                processes.size(),
                parameters as f64 * 4e-9 / (median / 1e3),
            );
        }
    }
}

/// Registers every float parameter's value as its gradient.
struct Register<'a> {
    grads: &'a mut GradientsParams,
}

impl burn::module::ModuleVisitor for Register<'_> {
    fn visit_float<const D: usize>(
        &mut self,
        param: &burn::module::Param<burn::tensor::Tensor<D>>,
    ) {
        self.grads.register(param.id, param.val());
    }
}
