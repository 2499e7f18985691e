//! How the ranks of a run end on an error. An error every rank met alike
//! (a check they made together, a stop they voted) is printed once, by
//! rank 0, before any rank ends (the launcher ends the others as soon as
//! one fails); an error one rank met alone, while the others wait for it
//! in a collective call, is printed with the rank's number and ends them
//! all.

use std::error::Error;

use super::LaunchError;
use crate::distributed::Collective;
use crate::error::TrainError;

/// The run stopped on request (Ctrl-C, SIGTERM, SIGUSR1) with a
/// checkpoint: an error, so that the command fails, and one every rank
/// meets alike.
#[derive(Debug)]
pub struct Stopped {
    /// Steps taken.
    pub steps: usize,
    /// Steps of the whole run.
    pub total: usize,
}

impl std::fmt::Display for Stopped {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "stopped after step {} of {}; a checkpoint is saved, run the same command to resume",
            self.steps, self.total
        )
    }
}

impl Error for Stopped {}

/// An error every rank met alike (the ranks disagree, a rank's device
/// failed, the run stopped), which rank 0 has printed: every rank ends
/// with a failure and prints nothing more.
#[derive(Debug)]
pub struct ReportedByRankZero;

impl std::fmt::Display for ReportedByRankZero {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("reported by rank 0")
    }
}

impl Error for ReportedByRankZero {}

/// Whether every rank has `error`: it came from a check the ranks made
/// together, or the ranks stopped together.
fn met_by_every_rank(error: &(dyn Error + 'static)) -> bool {
    let together = |e: &TrainError| matches!(e, TrainError::Distributed(_));
    let mut cause = Some(error);
    while let Some(here) = cause {
        if here.downcast_ref().is_some_and(together)
            || matches!(here.downcast_ref(), Some(LaunchError::Run(e)) if together(e))
            || here.is::<Stopped>()
            || here.is::<ReportedByRankZero>()
        {
            return true;
        }
        cause = here.source();
    }
    false
}

/// Ends this rank's part of a run of `processes` that failed with `error`
/// (in words: `description`). Met by every rank: rank 0 prints it, every
/// rank waits until it has, and the error becomes [`ReportedByRankZero`].
/// Met by this rank alone: it is printed with the rank and ends every
/// rank at once.
pub fn settle(
    processes: &dyn Collective,
    error: &(dyn Error + 'static),
    description: &str,
) -> ReportedByRankZero {
    if met_by_every_rank(error) {
        if processes.rank() == 0 && !error.is::<ReportedByRankZero>() {
            eprintln!("error: {description}");
        }
        processes.gather(&[]);
        return ReportedByRankZero;
    }
    eprintln!(
        "error: rank {} of {}: {description}",
        processes.rank(),
        processes.size()
    );
    processes.abort(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An error wrapping another, as a front end's context does.
    #[derive(Debug)]
    struct Context(Box<dyn Error + 'static>);

    impl std::fmt::Display for Context {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("while training")
        }
    }

    impl Error for Context {
        fn source(&self) -> Option<&(dyn Error + 'static)> {
            Some(self.0.as_ref())
        }
    }

    #[test]
    fn shared_errors_are_found_anywhere_in_the_chain_and_others_are_not() {
        let disagree = || TrainError::Distributed("the ranks disagree".into());
        assert!(met_by_every_rank(&Context(Box::new(disagree()))));
        assert!(met_by_every_rank(&LaunchError::Run(disagree())));
        assert!(met_by_every_rank(&Stopped { steps: 2, total: 4 }));
        assert!(met_by_every_rank(&ReportedByRankZero));
        let alone = TrainError::Input("rank 1's disk is full".into());
        assert!(!met_by_every_rank(&Context(Box::new(alone))));
        assert!(!met_by_every_rank(&LaunchError::Usage("no device".into())));
    }
}
