//! The processes of an MPI job (`mpirun -np N`, `srun`) as the
//! [`Collective`] a data-parallel training run is spread over: the
//! gradient all-reduce is `MPI_Allreduce` over one flat f32 buffer (into a
//! second buffer kept from the previous step, since rsmpi offers no
//! `MPI_IN_PLACE`: no copy and no fresh allocation per step), the
//! ranks' agreement checks gather their bytes with `MPI_Allgatherv`, and
//! each process learns its rank on its node from `MPI_Comm_split_type`
//! (shared memory), whatever the launcher.
//!
//! The engine is the system's MPI (Open MPI, MPICH, Intel MPI), linked
//! through rsmpi; building this crate needs its development files and
//! libclang (Debian: `libopenmpi-dev libclang-dev`).

use std::cell::RefCell;

use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::environment::Universe;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use mbs_train::distributed::Collective;

/// This process's place in the MPI job it was launched in.
pub struct MpiProcesses {
    /// Finalises MPI when dropped.
    _universe: Universe,
    world: SimpleCommunicator,
    local_rank: usize,
    /// The buffer the next sum is received into: the one the previous sum
    /// sent (the same length, its pages already mapped).
    spare: RefCell<Vec<f32>>,
}

impl MpiProcesses {
    /// Initialises MPI and joins the job's world; `None` when MPI was
    /// already initialised in this process.
    pub fn join() -> Option<Self> {
        let universe = mpi::initialize()?;
        let world = universe.world();
        let node = world.split_shared(world.rank());
        let local_rank = node.rank() as usize;
        Some(Self {
            _universe: universe,
            world,
            local_rank,
            spare: RefCell::new(Vec::new()),
        })
    }
}

impl Collective for MpiProcesses {
    fn rank(&self) -> usize {
        self.world.rank() as usize
    }

    fn size(&self) -> usize {
        self.world.size() as usize
    }

    /// The rank among the processes that share memory with this one
    /// (`MPI_Comm_split_type`), whatever the launcher.
    fn local_rank(&self) -> usize {
        self.local_rank
    }

    /// `MPI_Abort` on the world.
    fn abort(&self, code: i32) -> ! {
        self.world.abort(code)
    }

    /// `MPI_Allreduce` of `values` into the spare buffer, which is
    /// returned; `values` becomes the spare.
    fn sum(&self, values: Vec<f32>) -> Vec<f32> {
        let mut sums = self.spare.replace(values);
        let sent = self.spare.borrow();
        sums.resize(sent.len(), 0.0);
        self.world
            .all_reduce_into(&sent[..], &mut sums[..], SystemOperation::sum());
        sums
    }

    fn gather(&self, bytes: &[u8]) -> Vec<Vec<u8>> {
        let size = self.world.size() as usize;
        let mut counts = vec![0i32; size];
        self.world
            .all_gather_into(&(bytes.len() as i32), &mut counts[..]);
        let displacements: Vec<i32> = counts
            .iter()
            .scan(0, |start, &count| {
                let here = *start;
                *start += count;
                Some(here)
            })
            .collect();
        let total = counts.iter().map(|&c| c as usize).sum();
        if total == 0 {
            // A barrier: MPI refuses a gather of nothing into nothing.
            return vec![Vec::new(); size];
        }
        let mut all = vec![0u8; total];
        {
            let mut partition = PartitionMut::new(&mut all[..], &counts[..], &displacements[..]);
            self.world.all_gather_varcount_into(bytes, &mut partition);
        }
        counts
            .iter()
            .zip(&displacements)
            .map(|(&count, &start)| all[start as usize..(start + count) as usize].to_vec())
            .collect()
    }
}
