//! The benchmark folder flags (`--kitti`, `--middlebury`, `--eth3d`,
//! `--drivingstereo`, `--sceneflow`), made from mbs-dataset's table of
//! layouts ([`Benchmark::layout`]) so that a new layout needs no flag of
//! its own here, and shared by `predict` and `eval` (one folder), `submit`
//! (one folder of a benchmark with an evaluation server) and `benchmark`
//! (any number).

use std::marker::PhantomData;
use std::path::PathBuf;

use clap::{Arg, ArgAction, ArgGroup, ArgMatches, Command, FromArgMatches};
use mbs_dataset::benchmark::Benchmark;
use mbs_dataset::submission::SubmissionLayout;

/// The id of the flags' group, for other flags' conflicts.
pub const GROUP: &str = "benchmark-folder";

/// Which benchmarks' flags a command takes, and how many folders.
pub trait Selection {
    /// The benchmarks whose folders the command reads.
    const BENCHMARKS: &'static [Benchmark];
    /// Whether each flag may be repeated and several flags given.
    const MANY: bool;
    /// Whether a folder must be given.
    const REQUIRED: bool;
}

/// One folder of any benchmark, or none (`predict`, `eval`: their pairs
/// may come from elsewhere).
pub struct AnyOne;

impl Selection for AnyOne {
    const BENCHMARKS: &'static [Benchmark] = &Benchmark::ALL;
    const MANY: bool = false;
    const REQUIRED: bool = false;
}

/// Any number of folders of any benchmarks, at least one (`benchmark`).
pub struct Every;

impl Selection for Every {
    const BENCHMARKS: &'static [Benchmark] = &Benchmark::ALL;
    const MANY: bool = true;
    const REQUIRED: bool = true;
}

/// One folder of a benchmark with an evaluation server (`submit`).
pub struct OneWithServer;

impl Selection for OneWithServer {
    const BENCHMARKS: &'static [Benchmark] = &SubmissionLayout::SERVERS;
    const MANY: bool = false;
    const REQUIRED: bool = true;
}

/// The flags of `S`'s benchmarks in words: `--kitti, --middlebury or
/// --eth3d`, for messages that name them.
pub fn flags_in_words<S: Selection>() -> String {
    let flags: Vec<String> = S::BENCHMARKS
        .iter()
        .map(|b| format!("--{}", b.layout().flag))
        .collect();
    match flags.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    }
}

/// The benchmark folders the flags give: by benchmark in table order,
/// each flag's folders in the order given.
pub struct BenchmarkFolders<S> {
    /// Each folder with its benchmark.
    pub folders: Vec<(Benchmark, PathBuf)>,
    selection: PhantomData<S>,
}

impl<S> BenchmarkFolders<S> {
    /// The first folder given, if any (the only one where `S` takes one).
    pub fn first(&self) -> Option<(Benchmark, &PathBuf)> {
        self.folders.first().map(|(b, dir)| (*b, dir))
    }
}

impl<S: Selection> clap::Args for BenchmarkFolders<S> {
    fn augment_args(cmd: Command) -> Command {
        let flags = S::BENCHMARKS.iter().map(|b| b.layout().flag);
        let group = ArgGroup::new(GROUP)
            .args(flags)
            .multiple(S::MANY)
            .required(S::REQUIRED);
        S::BENCHMARKS
            .iter()
            .fold(cmd, |cmd, &benchmark| cmd.arg(folder_flag::<S>(benchmark)))
            .group(group)
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}

/// The flag naming folders of `benchmark`, with its layout as help.
fn folder_flag<S: Selection>(benchmark: Benchmark) -> Arg {
    let layout = benchmark.layout();
    let action = if S::MANY {
        ArgAction::Append
    } else {
        ArgAction::Set
    };
    Arg::new(layout.flag)
        .long(layout.flag)
        .value_name("DIR")
        .value_parser(clap::value_parser!(PathBuf))
        .action(action)
        .help(layout.folder)
}

impl<S: Selection> FromArgMatches for BenchmarkFolders<S> {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        let folders = S::BENCHMARKS
            .iter()
            .flat_map(|&benchmark| {
                let given = matches.get_many::<PathBuf>(benchmark.layout().flag);
                given
                    .into_iter()
                    .flatten()
                    .map(move |dir| (benchmark, dir.clone()))
            })
            .collect();
        Ok(Self {
            folders,
            selection: PhantomData,
        })
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(matches)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Parser)]
    struct Several {
        #[command(flatten)]
        folders: BenchmarkFolders<Every>,
    }

    #[derive(Parser)]
    struct Submission {
        #[command(flatten)]
        folders: BenchmarkFolders<OneWithServer>,
    }

    #[test]
    fn repeated_flags_keep_table_then_flag_order() {
        let args = Several::try_parse_from([
            "b",
            "--eth3d",
            "e",
            "--kitti",
            "k15",
            "--sceneflow",
            "s",
            "--kitti",
            "k12",
        ])
        .unwrap();
        let got: Vec<(Benchmark, &str)> = args
            .folders
            .folders
            .iter()
            .map(|(b, d)| (*b, d.to_str().unwrap()))
            .collect();
        assert_eq!(
            got,
            [
                (Benchmark::Kitti, "k15"),
                (Benchmark::Kitti, "k12"),
                (Benchmark::Eth3d, "e"),
                (Benchmark::SceneFlow, "s"),
            ]
        );
        let none = Several::try_parse_from(["b"]).err().unwrap().to_string();
        assert!(none.contains("required"), "{none}");
    }

    #[test]
    fn submission_takes_one_folder_of_a_server_benchmark() {
        let one = Submission::try_parse_from(["s", "--middlebury", "m"]).unwrap();
        assert_eq!(
            one.folders.first(),
            Some((Benchmark::Middlebury, &PathBuf::from("m")))
        );
        for bad in [
            vec!["s", "--kitti", "a", "--eth3d", "b"],
            vec!["s", "--kitti", "a", "--kitti", "b"],
            vec!["s", "--sceneflow", "a"],
        ] {
            assert!(Submission::try_parse_from(&bad).is_err(), "{bad:?}");
        }
    }
}
