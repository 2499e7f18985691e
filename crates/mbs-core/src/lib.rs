//! Rig geometry, image / disparity / depth types, file formats with atomic
//! and confined writing, and settings in layers, shared by every mbs crate
//! (operations on images are `mbs-image`'s, scoring is `mbs-eval`'s).
//!
//! Conventions (see `docs/conventions.md` §2): cameras sit on one horizontal line, camera
//! `k` at `x = k * B`; disparity is a non-negative magnitude on the reference
//! grid; invalid depth or disparity is `+inf` in memory and in float files,
//! and `0` in integer files.

pub mod atomic;
pub mod batch_settings;
pub mod confine;
pub mod error;
pub mod formats;
pub mod geometry;
pub mod inputs;
pub mod layered;
pub mod limits;
pub mod list_file;
pub mod lock;
pub mod out_dir;
pub mod regular;
pub mod shard;

pub use error::{FormatError, Result};
pub use geometry::{Rig, Side};

/// A single-channel float image: depth in metres or disparity in pixels.
/// Invalid pixels hold `f32::INFINITY`.
pub type FloatImage = image::ImageBuffer<image::Luma<f32>, Vec<f32>>;

/// An 8-bit RGB image, the currency for camera views.
pub type RgbImage = image::RgbImage;

/// An 8-bit single-channel image, used for masks (255 = set, 0 = clear).
pub type MaskImage = image::GrayImage;
