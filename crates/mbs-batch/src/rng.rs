//! The random generators of a run: every random choice of batch `k` comes
//! from a generator seeded by the run's seed and `k` alone ([`step_rng`]),
//! so a resumed run, another process or a Python data loader worker draws
//! exactly the batches an uninterrupted run would, whatever the timing.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Which random stream of a step a generator serves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// Sample, triplet and crop choices (worker threads).
    Batch,
    /// The student's augmentation (training thread).
    Augment,
}

/// The generator of `stream` for step `step` of a run seeded with `seed`.
pub fn step_rng(seed: u64, step: usize, stream: Stream) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let lane = match stream {
        Stream::Batch => 0,
        Stream::Augment => 1,
    };
    rng.set_stream(((step as u64) << 1) | lane);
    rng
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn step_generators_depend_on_seed_step_and_stream_only() {
        let first = |seed, step, stream| step_rng(seed, step, stream).random::<u64>();
        assert_eq!(first(1, 5, Stream::Batch), first(1, 5, Stream::Batch));
        assert_ne!(first(1, 5, Stream::Batch), first(1, 6, Stream::Batch));
        assert_ne!(first(1, 5, Stream::Batch), first(1, 5, Stream::Augment));
        assert_ne!(first(1, 5, Stream::Batch), first(2, 5, Stream::Batch));
    }
}
