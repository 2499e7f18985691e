//! One of the N shards of a batch (`--shard K/N`: job K, 0-based, of a
//! cluster job array takes items K, K+N, K+2N… of the sorted item list;
//! `--shard auto` reads K and N from the launcher, [`Shard::from_launcher`]),
//! and the rank and size of a process a launcher (`mpirun`, `srun`)
//! started ([`Shard::of_launch`]), which a training run joins on.

use std::str::FromStr;

/// One of N shards of a batch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This job's index, 0-based.
    pub index: usize,
    /// The number of jobs.
    pub count: usize,
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s.trim() == "auto" {
            return Shard::from_launcher(|name| std::env::var(name).ok());
        }
        let usage =
            || format!("invalid shard {s:?}: expected K/N with 0 <= K < N, e.g. 0/4, or auto");
        let (k, n) = s.split_once('/').ok_or_else(usage)?;
        let index: usize = k.trim().parse().map_err(|_| usage())?;
        let count: usize = n.trim().parse().map_err(|_| usage())?;
        if count == 0 || index >= count {
            return Err(usage());
        }
        Ok(Shard { index, count })
    }
}

/// The variables that give a process its rank and its launch's size, in
/// the order [`Shard::of_launch`] reads them (rank, then size).
pub const LAUNCH_VARIABLES: [&str; 6] = [
    "OMPI_COMM_WORLD_RANK",
    "OMPI_COMM_WORLD_SIZE",
    "PMI_RANK",
    "PMI_SIZE",
    "SLURM_PROCID",
    "SLURM_STEP_NUM_TASKS",
];

impl Shard {
    /// This process's shard from the variables its launcher sets (`var`
    /// reads one, `None` when unset):
    /// - a SLURM job array: `SLURM_ARRAY_TASK_ID` counted from
    ///   `SLURM_ARRAY_TASK_MIN` in steps of `SLURM_ARRAY_TASK_STEP`, of
    ///   `SLURM_ARRAY_TASK_COUNT`;
    /// - the processes of one launch: MPI's rank and size (Open MPI's
    ///   `OMPI_COMM_WORLD_RANK`/`_SIZE`, MPICH's and Intel MPI's
    ///   `PMI_RANK`/`PMI_SIZE`), else the tasks of an `srun` step
    ///   (`SLURM_PROCID`/`SLURM_STEP_NUM_TASKS`; not `SLURM_NTASKS`, which
    ///   a batch script sees too, where it runs one process).
    ///
    /// Both at once (an array of multi-process jobs) make `array × processes`
    /// shards. An error when neither is set or a value is not a number.
    pub fn from_launcher(var: impl Fn(&str) -> Option<String>) -> Result<Self, String> {
        let prefixed = |e: String| format!("--shard auto: {e}");
        let array = match variable_pair(&var, "SLURM_ARRAY_TASK_ID", "SLURM_ARRAY_TASK_COUNT")
            .map_err(prefixed)?
        {
            Some(Shard { index, count }) => Some(array_task(&var, index, count).map_err(prefixed)?),
            None => None,
        };
        let processes = Self::of_launch(&var).map_err(prefixed)?;
        let shard = match (array, processes) {
            (Some(array), Some(processes)) => {
                let index = array
                    .index
                    .checked_mul(processes.count)
                    .and_then(|first| first.checked_add(processes.index));
                let count = array.count.checked_mul(processes.count);
                let (Some(index), Some(count)) = (index, count) else {
                    return Err(format!(
                        "--shard auto: the array's {} tasks times the launch's {} processes \
                         overflow a shard number",
                        array.count, processes.count
                    ));
                };
                Shard { index, count }
            }
            (Some(one), None) | (None, Some(one)) => one,
            (None, None) => {
                return Err(
                    "--shard auto: no launcher set this process's shard (looked for \
                     SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT, OMPI_COMM_WORLD_RANK/\
                     OMPI_COMM_WORLD_SIZE, PMI_RANK/PMI_SIZE and SLURM_PROCID/\
                     SLURM_STEP_NUM_TASKS); give --shard K/N"
                        .into(),
                );
            }
        };
        if shard.count == 0 || shard.index >= shard.count {
            return Err(format!(
                "--shard auto: the launcher's variables give shard {}/{}, which is not one of \
                 0/N to N-1/N",
                shard.index, shard.count
            ));
        }
        Ok(shard)
    }

    /// This process's rank and the number of processes of its launch
    /// (`mpirun`, `srun`), from the variables [`Shard::from_launcher`]
    /// reads for them; `None` when no launcher set them.
    /// A rank that is not one of its launch's (`RANK=3` with `SIZE=1`, a
    /// size of 0) is an error naming both variables: such a process would
    /// otherwise run alone as if no launcher had started it.
    pub fn of_launch(var: impl Fn(&str) -> Option<String>) -> Result<Option<Self>, String> {
        for pair in LAUNCH_VARIABLES.chunks_exact(2) {
            if let Some(shard) = variable_pair(&var, pair[0], pair[1])? {
                if shard.index >= shard.count {
                    return Err(format!(
                        "{}={} and {}={} give shard {}/{}, a rank that is not one of the \
                         launch's processes (0 to size - 1): unset them to run one process, \
                         or start the processes with mpirun or srun",
                        pair[0], shard.index, pair[1], shard.count, shard.index, shard.count
                    ));
                }
                return Ok(Some(shard));
            }
        }
        Ok(None)
    }

    /// Keeps this shard's items of an already sorted list.
    pub fn select<T>(self, items: Vec<T>) -> Vec<T> {
        items
            .into_iter()
            .enumerate()
            .filter(|(i, _)| i % self.count == self.index)
            .map(|(_, item)| item)
            .collect()
    }
}

/// A SLURM array task's shard: its `SLURM_ARRAY_TASK_ID` (`id`) counted
/// from `SLURM_ARRAY_TASK_MIN` in steps of `SLURM_ARRAY_TASK_STEP`, of
/// `count` tasks. An id below the minimum, past the last task or off the
/// step is refused: it would run another task's shard (or none).
fn array_task(
    var: &impl Fn(&str) -> Option<String>,
    id: usize,
    count: usize,
) -> Result<Shard, String> {
    let first = number(var, "SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
    let step = number(var, "SLURM_ARRAY_TASK_STEP")?.unwrap_or(1);
    if step == 0 {
        return Err("SLURM_ARRAY_TASK_STEP=0 is not a step; expected 1 or more".into());
    }
    let last = count
        .checked_sub(1)
        .and_then(|tasks| tasks.checked_mul(step))
        .and_then(|span| span.checked_add(first));
    let on_the_array =
        id >= first && last.is_some_and(|last| id <= last) && (id - first).is_multiple_of(step);
    if !on_the_array {
        let ids = match last {
            Some(last) => format!("ids {first} to {last} in steps of {step}"),
            None => "no ids".into(),
        };
        return Err(format!(
            "SLURM_ARRAY_TASK_ID={id} is not a task of the array that SLURM_ARRAY_TASK_MIN={first}, \
             SLURM_ARRAY_TASK_STEP={step} and SLURM_ARRAY_TASK_COUNT={count} describe ({ids}); \
             it would run another task's shard"
        ));
    }
    Ok(Shard {
        index: (id - first) / step,
        count,
    })
}

/// The number in the variable `name` (`None` when unset).
fn number(var: &impl Fn(&str) -> Option<String>, name: &str) -> Result<Option<usize>, String> {
    var(name)
        .map(|value| {
            value
                .trim()
                .parse()
                .map_err(|_| format!("{name}={value:?} is not a non-negative integer"))
        })
        .transpose()
}

/// The index and count in the variables `index` and `count`, when both are set.
fn variable_pair(
    var: &impl Fn(&str) -> Option<String>,
    index: &str,
    count: &str,
) -> Result<Option<Shard>, String> {
    match (number(var, index)?, number(var, count)?) {
        (Some(index), Some(count)) => Ok(Some(Shard { index, count })),
        _ => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An array and a launch whose product passes `usize` is refused in
    /// words (it used to overflow a multiplication and panic).
    #[test]
    fn an_overflowing_array_times_launch_is_an_error() {
        let huge = usize::MAX.to_string();
        let vars = [
            ("SLURM_ARRAY_TASK_ID", "1"),
            ("SLURM_ARRAY_TASK_COUNT", huge.as_str()),
            ("OMPI_COMM_WORLD_RANK", "1"),
            ("OMPI_COMM_WORLD_SIZE", "4"),
        ];
        let var = |name: &str| {
            vars.iter()
                .find(|(key, _)| *key == name)
                .map(|(_, value)| value.to_string())
        };
        let err = Shard::from_launcher(var).unwrap_err();
        assert!(
            err.contains("overflow") && err.contains("4 processes"),
            "{err}"
        );
    }

    /// A rank past its launch's size used to be ignored with a size of 1,
    /// so the process trained alone.
    #[test]
    fn a_rank_outside_its_launch_is_refused() {
        for (rank, size) in [("3", "1"), ("0", "0"), ("2", "2")] {
            let vars = [
                ("OMPI_COMM_WORLD_RANK", rank),
                ("OMPI_COMM_WORLD_SIZE", size),
            ];
            let var = |name: &str| {
                vars.iter()
                    .find(|(key, _)| *key == name)
                    .map(|(_, value)| value.to_string())
            };
            let err = Shard::of_launch(var).unwrap_err();
            assert!(
                err.contains(&format!("OMPI_COMM_WORLD_RANK={rank}"))
                    && err.contains("not one of the launch's processes"),
                "{err}"
            );
        }
    }

    #[test]
    fn parses_and_selects_round_robin() {
        let shard: Shard = "1/3".parse().unwrap();
        assert_eq!(shard.select((0..8).collect()), vec![1, 4, 7]);
    }

    #[test]
    fn shards_cover_everything_once() {
        let mut all: Vec<i32> = (0..3)
            .flat_map(|k| Shard { index: k, count: 3 }.select((0..10).collect()))
            .collect();
        all.sort();
        assert_eq!(all, (0..10).collect::<Vec<_>>());
    }

    /// `--shard auto` from the environment `vars`.
    fn resolve(vars: &[(&str, &str)]) -> Result<Shard, String> {
        Shard::from_launcher(|name| {
            vars.iter()
                .find(|(key, _)| *key == name)
                .map(|(_, value)| value.to_string())
        })
    }

    /// `--shard auto` under each launcher, from a given environment.
    #[test]
    fn auto_reads_each_launcher() {
        let shard = |index, count| Ok(Shard { index, count });
        // A SLURM array of 16 numbered 1..16, task 5.
        let array = [
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "16"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
        ];
        assert_eq!(resolve(&array), shard(4, 16));
        // An array 0-14:2 (8 tasks), task 6.
        let stepped = [
            ("SLURM_ARRAY_TASK_ID", "6"),
            ("SLURM_ARRAY_TASK_COUNT", "8"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_STEP", "2"),
        ];
        assert_eq!(resolve(&stepped), shard(3, 8));
        // Its last task, 14, and the first of an array 3-4 (the case that
        // ran shard 0 for task 1 before).
        let last = [
            ("SLURM_ARRAY_TASK_ID", "14"),
            ("SLURM_ARRAY_TASK_COUNT", "8"),
            ("SLURM_ARRAY_TASK_STEP", "2"),
        ];
        assert_eq!(resolve(&last), shard(7, 8));
        let from_three = [
            ("SLURM_ARRAY_TASK_ID", "3"),
            ("SLURM_ARRAY_TASK_MIN", "3"),
            ("SLURM_ARRAY_TASK_COUNT", "2"),
        ];
        assert_eq!(resolve(&from_three), shard(0, 2));
        let ompi = [("OMPI_COMM_WORLD_RANK", "2"), ("OMPI_COMM_WORLD_SIZE", "3")];
        assert_eq!(resolve(&ompi), shard(2, 3));
        assert_eq!(
            resolve(&[("PMI_RANK", "1"), ("PMI_SIZE", "4")]),
            shard(1, 4)
        );
        let srun = [("SLURM_PROCID", "3"), ("SLURM_STEP_NUM_TASKS", "8")];
        assert_eq!(resolve(&srun), shard(3, 8));
        // mpirun inside a batch script: MPI's rank, not the script's task.
        let batch_script = [
            ("SLURM_PROCID", "0"),
            ("SLURM_STEP_NUM_TASKS", "1"),
            ("OMPI_COMM_WORLD_RANK", "1"),
            ("OMPI_COMM_WORLD_SIZE", "3"),
        ];
        assert_eq!(resolve(&batch_script), shard(1, 3));
        // Task 5 (of 16, from 1) running rank 2 of 3: 4 * 3 + 2 of 48.
        let both = [array.as_slice(), ompi.as_slice()].concat();
        assert_eq!(resolve(&both), shard(14, 48));
    }

    /// Environments that name no shard, each with what its error says:
    /// nothing set, SLURM_NTASKS alone (a batch script), bad values.
    const NO_SHARD: &[(&[(&str, &str)], &str)] = &[
        (&[], "no launcher set"),
        (&[("SLURM_NTASKS", "4")], "no launcher set"),
        (
            &[("PMI_RANK", "x"), ("PMI_SIZE", "2")],
            "PMI_RANK=\"x\" is not",
        ),
        (&[("PMI_RANK", "2"), ("PMI_SIZE", "2")], "give shard 2/2"),
        // Array tasks outside [MIN, MIN + COUNT * STEP) or off the step.
        (
            &[
                ("SLURM_ARRAY_TASK_ID", "1"),
                ("SLURM_ARRAY_TASK_MIN", "3"),
                ("SLURM_ARRAY_TASK_COUNT", "2"),
            ],
            "SLURM_ARRAY_TASK_ID=1 is not a task of the array",
        ),
        (
            &[
                ("SLURM_ARRAY_TASK_ID", "5"),
                ("SLURM_ARRAY_TASK_MIN", "3"),
                ("SLURM_ARRAY_TASK_COUNT", "2"),
            ],
            "SLURM_ARRAY_TASK_MIN=3",
        ),
        (
            &[
                ("SLURM_ARRAY_TASK_ID", "7"),
                ("SLURM_ARRAY_TASK_MIN", "0"),
                ("SLURM_ARRAY_TASK_STEP", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "8"),
            ],
            "SLURM_ARRAY_TASK_STEP=2",
        ),
        (
            &[
                ("SLURM_ARRAY_TASK_ID", "16"),
                ("SLURM_ARRAY_TASK_MIN", "0"),
                ("SLURM_ARRAY_TASK_STEP", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "8"),
            ],
            "SLURM_ARRAY_TASK_COUNT=8",
        ),
        (
            &[
                ("SLURM_ARRAY_TASK_ID", "0"),
                ("SLURM_ARRAY_TASK_STEP", "0"),
                ("SLURM_ARRAY_TASK_COUNT", "2"),
            ],
            "SLURM_ARRAY_TASK_STEP=0 is not a step",
        ),
        (
            &[
                ("SLURM_ARRAY_TASK_ID", "0"),
                ("SLURM_ARRAY_TASK_COUNT", "0"),
            ],
            "SLURM_ARRAY_TASK_COUNT=0",
        ),
    ];

    /// `--shard auto` with no launcher, or with values that name no shard.
    #[test]
    fn auto_refuses_what_names_no_shard() {
        for (vars, message) in NO_SHARD {
            let error = resolve(vars).unwrap_err();
            assert!(error.contains(message), "{vars:?}: {error}");
        }
    }

    #[test]
    fn rejects_bad_shards() {
        for bad in ["3/3", "1", "a/2", "0/0", "-1/2"] {
            assert!(
                bad.parse::<Shard>().unwrap_err().contains("expected K/N"),
                "{bad}"
            );
        }
    }
}
