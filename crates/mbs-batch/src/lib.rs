//! Host batches of S3 training, without burn: the training samples of a
//! manifest ([`samples`]), a random triplet of views and a crop per item
//! ([`sampling`]), decoded into planar `[B, 3, H, W]` buffers ([`batch`]),
//! and the draws of the student's augmentation ([`augment`]), every choice
//! of step `k` from a generator of the run's seed and `k` ([`rng`]). The
//! trainer (`mbs-train`) and the Python package's `MultiBaselineDataset`
//! both build their batches here, so they are the same for the same seed
//! and step.

pub mod augment;
pub mod batch;
pub mod error;
pub mod rng;
pub mod samples;
pub mod sampling;

pub use augment::{AugmentConfig, AugmentDraws};
pub use batch::{
    HostBatch, MAX_BATCH_SIZE, MAX_DRAWS_PER_ITEM, MIN_CROP_SIDE, load_batch, load_share, share,
};
pub use error::BatchError;
pub use rng::{Stream, step_rng};
pub use samples::{TrainingSamples, ViewPaths};
pub use sampling::{Triplet, TripletSampler, all_triplets, draw_triplet};
