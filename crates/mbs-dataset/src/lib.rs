//! Dataset layouts (MBS20K, and the benchmarks: KITTI, Middlebury, ETH3D,
//! DrivingStereo, SceneFlow), the manifest model with its JSON Schema,
//! stereo pairs from any of them with their ground truth, and the on-disk checks behind `mbs-tool validate`.

pub mod benchmark;
pub mod checksum;
pub mod driving_stereo;
pub mod error;
pub mod ground_truth;
pub mod kitti;
pub mod manifest;
pub mod mbs20k;
pub mod pairs;
pub mod photos;
pub mod probe;
pub mod scene_flow;
pub mod schema;
pub mod stereo_pair;
pub mod submission;
pub mod two_view;
pub mod validate;
mod walk;

pub use error::DatasetError;
pub use manifest::{Manifest, PairGroundTruth, Provenance, Sample, Split};
pub use stereo_pair::StereoPair;

/// The file name of `path` as text; a name that is not UTF-8 is an error
/// naming it, since samples and outputs are named after files.
pub(crate) fn utf8_file_name(path: &std::path::Path) -> Result<&str, DatasetError> {
    path.file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| DatasetError::Layout {
            path: path.to_path_buf(),
            message:
                "the name is not valid UTF-8 (samples and outputs are named after files): rename it"
                    .into(),
        })
}
