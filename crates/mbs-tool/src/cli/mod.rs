//! Pieces shared by the subcommands: sharding, parallel batches with a
//! progress bar and a summary, thread-pool setup, ONNX Runtime flags.

pub mod batch;
pub mod onnx;
pub mod pair;
pub mod report_error;
pub mod rig;
pub mod shard;

/// Sets the number of worker threads (0 = one per core).
pub fn set_threads(jobs: usize) -> anyhow::Result<()> {
    if jobs > 0 {
        rayon::ThreadPoolBuilder::new()
            .num_threads(jobs)
            .build_global()
            .map_err(|e| anyhow::anyhow!("cannot start {jobs} worker threads: {e}"))?;
    }
    Ok(())
}
