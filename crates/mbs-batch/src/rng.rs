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
    /// The draws of item `i` of a batch after its first one met an
    /// unusable image: a generator of its own for each item, so that the
    /// items of one share of a batch (a process of a data-parallel run)
    /// never depend on the files of another share's items.
    Redraw(usize),
}

/// The key that sets the redraw generators ([`Stream::Redraw`]) apart from
/// the step's two streams, which share the run's seed.
const REDRAW_KEY: u64 = 0x5245_4452_4157_5321;

/// The generator of `stream` for step `step` of a run seeded with `seed`.
pub fn step_rng(seed: u64, step: usize, stream: Stream) -> ChaCha8Rng {
    let (key, stream) = match stream {
        Stream::Batch => (seed, (step as u64) << 1),
        Stream::Augment => (seed, ((step as u64) << 1) | 1),
        // Items are fewer than 2^16 (MAX_BATCH_SIZE).
        Stream::Redraw(item) => (seed ^ REDRAW_KEY, ((step as u64) << 16) | item as u64),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(key);
    rng.set_stream(stream);
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
        assert_ne!(
            first(1, 5, Stream::Redraw(0)),
            first(1, 5, Stream::Redraw(1))
        );
        assert_ne!(
            first(1, 5, Stream::Redraw(0)),
            first(1, 6, Stream::Redraw(0))
        );
        assert_ne!(first(1, 5, Stream::Redraw(0)), first(1, 5, Stream::Batch));
    }
}
