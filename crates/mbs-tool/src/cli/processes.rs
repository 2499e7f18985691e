//! The processes a launcher (`mpirun`, `srun`) started for one command:
//! joined into an MPI job in a build with `--features mpi`, refused in one
//! without, where each process would run alone and all would write the
//! same files.

use std::rc::Rc;

use mbs_train::distributed::Collective;

use super::shard::Shard;

/// The MPI job this process belongs to, when its launcher started several
/// processes; `None` when it runs alone.
pub fn join() -> anyhow::Result<Option<Rc<dyn Collective>>> {
    let launch = Shard::of_launch(|name| std::env::var(name).ok()).map_err(anyhow::Error::msg)?;
    let Some(launch) = launch.filter(|launch| launch.count > 1) else {
        return Ok(None);
    };
    join_mpi(launch.count)
}

/// Joins the MPI job, which must hold the `launched` processes the
/// launcher's variables announce: a process that finds itself alone in a
/// world of one (the variables set by hand or inherited, with no MPI job
/// behind them) would train alone into a folder another process writes too.
#[cfg(feature = "mpi")]
fn join_mpi(launched: usize) -> anyhow::Result<Option<Rc<dyn Collective>>> {
    let processes = mbs_mpi::MpiProcesses::join()
        .ok_or_else(|| anyhow::anyhow!("MPI was already initialised in this process"))?;
    let size = processes.size();
    if size != launched {
        anyhow::bail!(
            "the launcher's variables ({}) say {launched} processes, but MPI gives this process \
             a job of {size}: start the processes with mpirun or srun (with MPI support), or \
             unset those variables to run one process",
            launch_variables()
        );
    }
    Ok(Some(Rc::new(processes)))
}

/// The launcher variables that are set, as `NAME=VALUE` joined by commas.
#[cfg(feature = "mpi")]
fn launch_variables() -> String {
    super::shard::LAUNCH_VARIABLES
        .iter()
        .filter_map(|name| Some(format!("{name}={}", std::env::var(name).ok()?)))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(not(feature = "mpi"))]
fn join_mpi(launched: usize) -> anyhow::Result<Option<Rc<dyn Collective>>> {
    anyhow::bail!(
        "the launcher started {launched} processes, but this mbs-tool was built without MPI, \
         so each would train alone into the same folder: build it with \
         `cargo build --release -p mbs-tool --features mpi` (needs an MPI library and libclang; \
         Debian: apt-get install libopenmpi-dev libclang-dev), or run one process"
    )
}
