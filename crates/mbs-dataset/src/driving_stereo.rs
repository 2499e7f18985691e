//! DrivingStereo's weather subsets (sunny, cloudy, foggy, rainy), read from
//! a weather folder exactly as its downloads unpack: `left-image-full-size/`,
//! `right-image-full-size/` and `disparity-map-full-size/` (or the
//! `-half-size` ones), the three holding files of the same names. The
//! disparity PNGs are 16-bit, disparity = value / 256, 0 = no ground
//! truth. DrivingStereo has no occlusion mask, so its pairs have no NOC
//! pixels: only ALL is scored, as in the paper's table.

use std::path::{Path, PathBuf};

use mbs_core::Side;

use crate::DatasetError;
use crate::ground_truth::GroundTruthFile;
use crate::kitti::png_stems;
use crate::stereo_pair::StereoPair;

/// The image sizes DrivingStereo ships, largest first: the full-size
/// folders are read when a weather folder holds both.
const SIZES: [&str; 2] = ["full-size", "half-size"];

/// The three folders of one size: left views, right views, disparities.
fn folders(dir: &Path, size: &str) -> [PathBuf; 3] {
    ["left-image", "right-image", "disparity-map"].map(|kind| dir.join(format!("{kind}-{size}")))
}

/// Every frame of a DrivingStereo weather folder `dir` (full size when
/// present, else half size) as a right-side pair named after its file
/// stem, in name order, with its ground truth where the disparity folder
/// has the frame's file. A folder without the left and right image
/// folders of either size, or without frames, is a layout error naming
/// what was expected.
pub fn driving_stereo_pairs(dir: &Path) -> Result<Vec<StereoPair>, DatasetError> {
    let [left, right, disparity] = SIZES
        .iter()
        .map(|size| folders(dir, size))
        .find(|[left, right, _]| left.is_dir() && right.is_dir())
        .ok_or_else(|| DatasetError::Layout {
            path: dir.to_path_buf(),
            message: "not a DrivingStereo weather folder: expected left-image-full-size/ and \
                      right-image-full-size/ (or the -half-size ones)"
                .into(),
        })?;
    let frames = png_stems(&left)?;
    if frames.is_empty() {
        return Err(DatasetError::Layout {
            path: left,
            message: "no .png views".into(),
        });
    }
    Ok(frames
        .into_iter()
        .map(|frame| {
            let file = format!("{frame}.png");
            let truth = disparity.join(&file);
            StereoPair {
                cameras: (0, 1),
                reference: left.join(&file),
                target: right.join(&file),
                side: Side::Right,
                truth: truth.is_file().then_some(GroundTruthFile {
                    disparity: truth,
                    scale: 1.0,
                    noc: None,
                }),
                disparity_bound: None,
                calibration: None,
                id: frame,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_test_support::files::touch;

    #[test]
    fn frames_pair_by_name_with_their_disparity_maps() {
        let dir = tempfile::tempdir().unwrap();
        let sunny = dir.path().join("sunny");
        for frame in ["2018-10-19-09-30-39_2018-10-19-09-31-04-575", "a"] {
            touch(&sunny.join(format!("left-image-full-size/{frame}.png")));
            touch(&sunny.join(format!("right-image-full-size/{frame}.png")));
        }
        touch(&sunny.join("disparity-map-full-size/a.png"));
        let pairs = driving_stereo_pairs(&sunny).unwrap();
        assert_eq!(pairs.len(), 2);
        assert_eq!(pairs[0].id, "2018-10-19-09-30-39_2018-10-19-09-31-04-575");
        assert!(pairs[0].truth.is_none());
        let truth = pairs[1].truth.as_ref().unwrap();
        assert_eq!(truth.disparity, sunny.join("disparity-map-full-size/a.png"));
        assert_eq!(truth.noc, None);
        assert_eq!(pairs[1].target, sunny.join("right-image-full-size/a.png"));
    }

    #[test]
    fn half_size_folders_are_read_when_the_full_size_ones_are_missing() {
        let dir = tempfile::tempdir().unwrap();
        touch(&dir.path().join("left-image-half-size/f.png"));
        touch(&dir.path().join("right-image-half-size/f.png"));
        touch(&dir.path().join("disparity-map-half-size/f.png"));
        let pairs = driving_stereo_pairs(dir.path()).unwrap();
        assert_eq!(
            pairs[0].reference,
            dir.path().join("left-image-half-size/f.png")
        );
        assert!(pairs[0].truth.is_some());
    }

    #[test]
    fn other_folders_name_the_expected_layout() {
        let dir = tempfile::tempdir().unwrap();
        let err = driving_stereo_pairs(dir.path()).unwrap_err().to_string();
        assert!(
            err.contains("not a DrivingStereo weather folder")
                && err.contains("left-image-full-size"),
            "{err}"
        );
        std::fs::create_dir_all(dir.path().join("left-image-full-size")).unwrap();
        std::fs::create_dir_all(dir.path().join("right-image-full-size")).unwrap();
        let err = driving_stereo_pairs(dir.path()).unwrap_err().to_string();
        assert!(err.contains("no .png views"), "{err}");
    }
}
