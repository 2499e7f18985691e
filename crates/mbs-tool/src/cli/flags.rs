//! Flags that several commands take, declared once and flattened into
//! each command that takes them: `--jobs` ([`Jobs`]), `--shard` with
//! `--jobs` for batch commands ([`Batch`]), and `--overwrite`
//! ([`Overwrite`]).

use mbs_core::shard::Shard;

/// `--jobs`: the command's worker threads.
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct Jobs {
    /// Worker threads (0 = one per core).
    #[arg(long, default_value_t = 0, value_parser = super::values::jobs)]
    pub jobs: usize,
}

impl Jobs {
    /// Starts the worker threads asked for (0 leaves rayon's one per core).
    pub fn start(self) -> anyhow::Result<()> {
        let jobs = self.jobs;
        if jobs > 0 {
            rayon::ThreadPoolBuilder::new()
                .num_threads(jobs)
                .build_global()
                .map_err(|e| anyhow::anyhow!("cannot start {jobs} worker threads: {e}"))?;
        }
        Ok(())
    }
}

/// `--shard` and `--jobs`: how a batch command splits its items between
/// the jobs of a cluster and its threads.
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct Batch {
    /// Process only shard K of N (0-based), for cluster job arrays; a
    /// command that writes a manifest writes it when run once more without
    /// --shard. `auto` reads K and N from a SLURM array, `srun` or `mpirun`.
    #[arg(long, value_name = "K/N|auto")]
    pub shard: Option<Shard>,
    /// The worker threads.
    #[command(flatten)]
    pub threads: Jobs,
}

/// `--overwrite`: recompute what an earlier run wrote.
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct Overwrite {
    /// Recompute outputs that mbs wrote earlier (a file it did not write
    /// is refused, with or without this flag).
    #[arg(long)]
    pub overwrite: bool,
}
