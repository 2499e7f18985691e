//! The processes a launcher (`mpirun`, `srun`) started for one run: joined
//! into an MPI job by a front end that can join one, refused by one that
//! cannot, where each process would train alone and all would write the
//! same folder.

use std::rc::Rc;

use mbs_core::shard::{LAUNCH_VARIABLES, Shard};

use super::LaunchError;
use crate::distributed::Collective;

/// Joins the MPI job of this process's launch (a front end built with MPI
/// passes `mbs_mpi::MpiProcesses::join`); `None` when MPI was already
/// initialised in this process.
pub type MpiJoin<'a> = &'a dyn Fn() -> Option<Rc<dyn Collective>>;

/// The processes this one belongs to when its launcher started several
/// (from the launcher's variables, each read by `var`: `None` when unset),
/// joined through `mpi`; `None` when it runs alone. Refused: variables
/// that give no rank of their launch, a launch of several processes with
/// no `mpi` to join it ([`LaunchError::NoMpi`]), and an MPI job whose size
/// is not the launcher's count (the variables set by hand or inherited,
/// with no MPI job behind them).
pub fn join(
    var: impl Fn(&str) -> Option<String>,
    mpi: Option<MpiJoin<'_>>,
) -> Result<Option<Rc<dyn Collective>>, LaunchError> {
    let launch = Shard::of_launch(&var).map_err(LaunchError::Launcher)?;
    let Some(launch) = launch.filter(|launch| launch.count > 1) else {
        return Ok(None);
    };
    let launched = launch.count;
    let mpi = mpi.ok_or(LaunchError::NoMpi { launched })?;
    let processes = mpi().ok_or(LaunchError::MpiInitialised)?;
    let size = processes.size();
    if size != launched {
        let variables = LAUNCH_VARIABLES
            .iter()
            .filter_map(|name| Some(format!("{name}={}", var(name)?)))
            .collect::<Vec<_>>()
            .join(", ");
        return Err(LaunchError::JobSize {
            launched,
            size,
            variables,
        });
    }
    Ok(Some(processes))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distributed::tests::Threads;

    fn variables(
        pairs: &'static [(&'static str, &'static str)],
    ) -> impl Fn(&str) -> Option<String> {
        move |name| {
            pairs
                .iter()
                .find(|(key, _)| *key == name)
                .map(|(_, value)| value.to_string())
        }
    }

    #[test]
    fn a_process_alone_joins_nothing() {
        let never: MpiJoin<'_> = &|| panic!("no MPI job to join");
        assert!(join(variables(&[]), Some(never)).unwrap().is_none());
        let one = variables(&[("OMPI_COMM_WORLD_RANK", "0"), ("OMPI_COMM_WORLD_SIZE", "1")]);
        assert!(join(one, None).unwrap().is_none());
    }

    #[test]
    fn a_launch_of_several_needs_a_job_of_its_size() {
        let two = || variables(&[("PMI_RANK", "1"), ("PMI_SIZE", "2")]);
        let error = join(two(), None).err().unwrap();
        assert!(
            matches!(error, LaunchError::NoMpi { launched: 2 }),
            "{error}"
        );
        let initialised: MpiJoin<'_> = &|| None;
        let error = join(two(), Some(initialised)).err().unwrap();
        assert!(matches!(error, LaunchError::MpiInitialised), "{error}");
        let of_three: MpiJoin<'_> = &|| Some(Rc::new(Threads::group(3).remove(0)));
        let error = join(two(), Some(of_three)).err().unwrap().to_string();
        assert!(
            error.contains("(PMI_RANK=1, PMI_SIZE=2) say 2 processes"),
            "{error}"
        );
        assert!(error.contains("a job of 3"), "{error}");
        let of_two: MpiJoin<'_> = &|| Some(Rc::new(Threads::group(2).remove(1)));
        assert_eq!(join(two(), Some(of_two)).unwrap().unwrap().size(), 2);
        let outside = variables(&[("SLURM_PROCID", "3"), ("SLURM_STEP_NUM_TASKS", "2")]);
        let error = join(outside, None).err().unwrap().to_string();
        assert!(
            error.contains("a rank that is not one of the launch's"),
            "{error}"
        );
    }
}
