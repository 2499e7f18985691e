//! The processes a launcher (`mpirun`, `srun`) started for one command,
//! joined by the library ([`mbs_train::launch::join`]) into an MPI job in
//! a build with `--features mpi`; a build without refuses them with how to
//! build one that can.

use std::rc::Rc;

use mbs_train::distributed::Collective;
use mbs_train::launch::{LaunchError, MpiJoin};

/// The MPI job this process belongs to, when its launcher started several
/// processes; `None` when it runs alone.
pub fn join() -> anyhow::Result<Option<Rc<dyn Collective>>> {
    let variable = |name: &str| std::env::var(name).ok();
    match mbs_train::launch::join(variable, mpi()) {
        Err(LaunchError::NoMpi { launched }) => anyhow::bail!(
            "the launcher started {launched} processes, but this mbs-tool was built without MPI, \
             so each would train alone into the same folder: build it with \
             `cargo build --release -p mbs-tool --features mpi` (needs an MPI library and libclang; \
             Debian: apt-get install libopenmpi-dev libclang-dev), or run one process"
        ),
        joined => Ok(joined?),
    }
}

/// How this build joins an MPI job.
#[cfg(feature = "mpi")]
fn mpi() -> Option<MpiJoin<'static>> {
    Some(&|| {
        let processes = mbs_mpi::MpiProcesses::join()?;
        Some(Rc::new(processes) as Rc<dyn Collective>)
    })
}

/// This build cannot join an MPI job.
#[cfg(not(feature = "mpi"))]
fn mpi() -> Option<MpiJoin<'static>> {
    None
}
