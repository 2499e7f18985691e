//! Batches decoded on worker threads ahead of the training step. Worker `w`
//! of `W` loads steps `first + w`, `first + w + W`, ... into its own
//! two-slot channel, and the consumer reads the channels in turn, so
//! batches arrive in step order and at most `2 W` wait in memory. A
//! process of a data-parallel run loads only its share of each batch's
//! items.

use std::ops::Range;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use crate::error::TrainError;
use mbs_batch::TrainingSamples;
use mbs_batch::{HostBatch, load_share};

/// Batches waiting per worker.
const SLOTS: usize = 2;

/// Loads the batches of steps `first..end` ahead of their use.
pub struct BatchLoader {
    receivers: Vec<Receiver<Result<HostBatch, TrainError>>>,
    workers: Vec<JoinHandle<()>>,
    next: usize,
    first: usize,
    end: usize,
}

/// What one worker needs.
struct Job {
    samples: Arc<TrainingSamples>,
    batch_size: usize,
    items: Range<usize>,
    crop: (usize, usize),
    seed: u64,
    steps: std::iter::StepBy<Range<usize>>,
    sender: SyncSender<Result<HostBatch, TrainError>>,
}

impl Job {
    fn run(self) {
        for step in self.steps {
            let batch = load_share(
                &self.samples,
                self.batch_size,
                self.crop,
                self.seed,
                step,
                self.items.clone(),
            )
            .map_err(TrainError::from);
            let failed = batch.is_err();
            // A closed channel means the consumer stopped: nothing more to do.
            if self.sender.send(batch).is_err() || failed {
                return;
            }
        }
    }
}

impl BatchLoader {
    /// Starts `workers` threads loading the items `items` of the batches
    /// of `batch_size` items of steps `first..end`.
    pub fn start(
        samples: Arc<TrainingSamples>,
        (batch_size, items): (usize, Range<usize>),
        crop: (usize, usize),
        seed: u64,
        (first, end): (usize, usize),
        workers: usize,
    ) -> Self {
        let workers = workers.max(1);
        let mut receivers = Vec::with_capacity(workers);
        let mut handles = Vec::with_capacity(workers);
        for w in 0..workers {
            let (sender, receiver) = sync_channel(SLOTS);
            let job = Job {
                samples: Arc::clone(&samples),
                batch_size,
                items: items.clone(),
                crop,
                seed,
                steps: (first + w..end).step_by(workers),
                sender,
            };
            handles.push(std::thread::spawn(move || job.run()));
            receivers.push(receiver);
        }
        Self {
            receivers,
            workers: handles,
            next: first,
            first,
            end,
        }
    }

    /// The next batch in step order; `None` after the last step. A worker
    /// that died without sending gives an error instead of a hang.
    pub fn next_batch(&mut self) -> Option<Result<HostBatch, TrainError>> {
        if self.next >= self.end {
            return None;
        }
        let lane = (self.next - self.first) % self.receivers.len();
        self.next += 1;
        Some(self.receivers[lane].recv().unwrap_or_else(|_| {
            Err(TrainError::Data {
                path: "<loader>".into(),
                reason: "a loading thread stopped unexpectedly".into(),
            })
        }))
    }
}

impl Drop for BatchLoader {
    fn drop(&mut self) {
        // Closing the channels stops workers blocked on a full slot.
        self.receivers.clear();
        for worker in self.workers.drain(..) {
            let _ = worker.join();
        }
    }
}
