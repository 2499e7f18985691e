//! Dataset layouts (MBS20K, KITTI), the manifest model with its JSON Schema,
//! pairs with ground truth, and the on-disk checks behind `mbs-tool validate`.

pub mod checksum;
pub mod error;
pub mod ground_truth;
pub mod kitti;
pub mod manifest;
pub mod mbs20k;
pub mod probe;
pub mod schema;
pub mod validate;

#[cfg(test)]
mod test_util;

pub use error::DatasetError;
pub use manifest::{Manifest, PairGroundTruth, Provenance, Sample, Split};
