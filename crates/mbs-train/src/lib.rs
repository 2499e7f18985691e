//! S3 self-supervised multi-baseline stereo training on burn: losses, masks and weight map, EMA teacher, schedules, batches on the device (drawn by `mbs-batch`), checkpoints, and training runs with their logs, pictures and TensorBoard events; the networks it trains are `mbs-nets`'.
//!
//! Everything runs on burn's run-time selected device (`Device::flex()` on
//! CPU, Vulkan or CUDA through [`mbs_nets::device::open_device`],
//! `.autodiff()` for training; [`step::S3Trainer::step_parallel`] shares a
//! step among several, [`step::S3Trainer::step_shared`] among processes
//! through a [`distributed::Collective`] as well, each placement a
//! [`run::Strategy`]); [`launch::Launch`] opens a run on them for any front
//! end. See `docs/design.md` for the choice of burn.
//!
//! One step, as [`step::S3Trainer::step`] runs it:
//!
//! ```text
//! mbs_batch::load_batch     -> (reference r, student target t_s, teacher target t_t), r = B_s / B_t
//! augment::augment          -> colour jitter + occlusion of the student's pair
//! mbs_nets::predict         -> d_t = teacher(I_r, I_tt)     (no autodiff, left targets mirrored)
//!                              d_s = student(aug I_r, aug I_ts)
//! losses::S3Loss::compute   -> L = mean(A |d_s - r d_t|) + lambda_p mean(M_s P_s) + lambda_s L_s
//!                              (P, M on clean images; mask::weight_map gives A)
//! clip::clip_global_norm    -> Adam step at schedule::OneCycle::lr(step)
//! ema::ema_update           -> teacher <- m teacher + (1 - m) student, m = schedule::CosineMomentum
//! ```

pub mod augment;
pub mod checkpoint;
pub mod clip;
pub mod config;
pub mod data;
pub mod distributed;
pub mod drift;
pub mod ema;
pub mod error;
pub mod launch;
pub mod losses;
pub mod mask;
pub mod memory;
pub mod optimizer;
pub mod precision;
pub mod run;
pub mod schedule;
pub mod step;
pub mod supervision;
pub mod tensorboard;

pub use config::RunConfig;
pub use data::StepBatch;
pub use error::TrainError;
pub use losses::{LossConfig, LossInputs, LossOutput, S3Loss};
pub use mbs_batch::sampling;
pub use step::{S3Trainer, StepReport, TrainerConfig};

/// burn's CPU random generator is one per process: seeding it and drawing
/// a run's fresh weights under this lock keeps a seed's network the same
/// when several runs open at once in one process (as tests do).
pub(crate) static WEIGHT_DRAWING: std::sync::Mutex<()> = std::sync::Mutex::new(());
