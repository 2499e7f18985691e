//! One rectified stereo pair as every layout lists it (a benchmark's
//! folder, a manifest's samples, one pair of files): the type the layouts
//! build and the commands consume, below all of them.

use std::path::PathBuf;

use mbs_core::Side;
use mbs_core::inputs::InputFiles;

use crate::ground_truth::GroundTruthFile;

/// One rectified pair: the views, the side of the target and the
/// reference view's ground truth, if any.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoPair {
    /// The sample id (manifests), frame name (KITTI, e.g. `000000_10`) or
    /// the left view's file stem (one pair): outputs are named after it.
    pub id: String,
    /// Camera indices of the reference and target (KITTI and one pair: 0 and 1).
    pub cameras: (usize, usize),
    /// The reference view (the disparity lives on its grid).
    pub reference: PathBuf,
    /// The target view.
    pub target: PathBuf,
    /// Which side of the reference the target lies on.
    pub side: Side,
    /// The reference view's ground truth, when the dataset has it.
    pub truth: Option<GroundTruthFile>,
    /// The dataset's bound on the pair's disparities, when it states one:
    /// they lie in `0..n` (Middlebury's and ETH3D's `calib.txt` `ndisp`).
    pub disparity_bound: Option<u32>,
    /// The calibration file the layout read beside the views (Middlebury's
    /// and ETH3D's `calib.txt`), when there is one.
    pub calibration: Option<PathBuf>,
}

impl StereoPair {
    /// Every file the pair is read from: the views, the ground truth and
    /// its mask, and the calibration file beside the views.
    pub fn input_files(&self) -> Vec<PathBuf> {
        let mut files = vec![self.reference.clone(), self.target.clone()];
        if let Some(truth) = &self.truth {
            files.push(truth.disparity.clone());
            if let Some(noc) = &truth.noc {
                files.push(noc.path().to_path_buf());
            }
        }
        files.extend(self.calibration.clone());
        files
    }
}

/// Every input file of `pairs`, for refusing outputs that would replace one.
pub fn input_files<'a>(pairs: impl IntoIterator<Item = &'a StereoPair>) -> InputFiles {
    let mut inputs = InputFiles::new();
    inputs.extend(pairs.into_iter().flat_map(StereoPair::input_files));
    inputs
}
