//! The disparities of both views of a pair: read from files and checked,
//! derived from the other view's by warping, or estimated by a matcher
//! (the right view's by mirroring the pair).

use std::path::Path;

use mbs_core::formats::read_float_map;
use mbs_core::{FloatImage, RgbImage, Side};
use mbs_image::median::median_filter;
use mbs_infer::{Sgm, SgmConfig, SgmPaths, StereoMatcher};
use mbs_warp::{fill_disparity_background, forward_warp};

use crate::ExtrapolateError;

/// Radius of the median filter applied to the built-in matcher's
/// disparities before warping (a 5x5 square).
pub const SGM_MEDIAN_RADIUS: u32 = 2;

/// The built-in matcher's settings for warping, which differ from the
/// matching defaults (tuned for Out-N on Middlebury): all eight paths and
/// no uniqueness test, so fewer pixels are dropped and refilled from the
/// background. With the 5x5 median ([`SGM_MEDIAN_RADIUS`]) this gave
/// +0.6 dB PSNR over the 28 extrapolated views of the shipped real scenes
/// (`examples/extrapolation_eval.rs`) and +0.5 dB at twice the baseline;
/// larger penalties, a smaller census window, no left-right check or no
/// speckle removal each lost 0.2 to 1.5 dB there.
pub fn warping_sgm_config(max_disparity: u32) -> SgmConfig {
    SgmConfig {
        paths: SgmPaths::Eight,
        uniqueness: 0,
        ..SgmConfig::with_max_disparity(max_disparity)
    }
}

/// The disparities of a pair, each on its own view's grid, every pixel
/// finite (unknown pixels filled from the background side).
#[derive(Debug, Clone, PartialEq)]
pub struct Disparities {
    /// Disparity of the left view (towards the right one).
    pub left: FloatImage,
    /// Disparity of the right view (towards the left one).
    pub right: FloatImage,
}

/// Where disparities come from for a pair without disparity files.
pub enum DisparitySource {
    /// The built-in semi-global matcher with these settings, and a median
    /// filter on its output ([`SGM_MEDIAN_RADIUS`]).
    BuiltIn(SgmConfig),
    /// Any other matcher, e.g. an ONNX network or a trained teacher.
    Matcher(Box<dyn StereoMatcher>),
}

impl DisparitySource {
    /// The built-in matcher tuned for warping ([`warping_sgm_config`]),
    /// searching `max_disparity` disparities (0 = estimate per pair, see
    /// [`SgmConfig::max_disparity`]).
    pub fn builtin(max_disparity: u32) -> Self {
        DisparitySource::BuiltIn(warping_sgm_config(max_disparity))
    }

    /// Estimates both views' disparities of the pair.
    pub fn disparities(
        &self,
        left: &RgbImage,
        right: &RgbImage,
    ) -> Result<Disparities, ExtrapolateError> {
        let sgm;
        let (matcher, median_radius): (&dyn StereoMatcher, u32) = match self {
            DisparitySource::Matcher(matcher) => (matcher.as_ref(), 0),
            DisparitySource::BuiltIn(config) => {
                sgm = Sgm::new(*config);
                (&sgm, SGM_MEDIAN_RADIUS)
            }
        };
        let for_warping =
            |map: &FloatImage| median_filter(&fill_disparity_background(map), median_radius);
        Ok(Disparities {
            left: for_warping(&matcher.predict(left, right)?.disparity),
            right: for_warping(&matcher.predict_right(left, right)?.disparity),
        })
    }
}

/// Reads a disparity map for views of `size` (width, height): PFM, EXR or
/// KITTI 16-bit PNG. NaN or negative values, another size, or no valid
/// pixel at all are errors naming the file; unknown pixels (`+inf`, 0 in
/// PNGs) are filled from the background side.
pub fn load_disparity(path: &Path, size: (u32, u32)) -> Result<FloatImage, ExtrapolateError> {
    checked_disparity(read_float_map(path)?, size, path)
}

/// `map` as [`load_disparity`] checks and fills a file's disparity;
/// errors name `source` (the file, or the argument it came from).
pub fn checked_disparity(
    map: FloatImage,
    size: (u32, u32),
    source: &Path,
) -> Result<FloatImage, ExtrapolateError> {
    let bad = map.iter().filter(|d| d.is_nan() || **d < 0.0).count();
    if bad > 0 {
        return Err(ExtrapolateError::input(
            source,
            format!(
                "{bad} NaN or negative disparities (disparity is a non-negative magnitude; mark invalid pixels +inf or 0 in PNGs)"
            ),
        ));
    }
    if map.dimensions() != size {
        return Err(ExtrapolateError::input(
            source,
            format!(
                "disparity is {:?} but the views are {size:?} (width, height)",
                map.dimensions()
            ),
        ));
    }
    if !map.iter().any(|d| d.is_finite()) {
        return Err(ExtrapolateError::input(source, "no valid disparity at all"));
    }
    Ok(fill_disparity_background(&map))
}

/// The disparity of the other view of the pair: `disparity` (of `view`)
/// warped towards `side` with a z-buffer, disocclusions filled from the
/// background side.
pub fn derive_other_view(
    view: &RgbImage,
    disparity: &FloatImage,
    side: Side,
) -> Result<FloatImage, ExtrapolateError> {
    let warped = forward_warp(view, disparity, side)?;
    Ok(fill_disparity_background(&warped.disparity))
}

impl Disparities {
    /// Both views' disparities from the files given (one or both): a view
    /// without a file gets the other's warped to it. `None` when neither
    /// file is given.
    pub fn from_files(
        left_file: Option<&Path>,
        right_file: Option<&Path>,
        left: &RgbImage,
        right: &RgbImage,
    ) -> Result<Option<Disparities>, ExtrapolateError> {
        let size = left.dimensions();
        let load = |file: Option<&Path>| file.map(|f| load_disparity(f, size)).transpose();
        let (left_map, right_map) = (load(left_file)?, load(right_file)?);
        Self::from_maps(left_map, right_map, left, right)
    }

    /// Both views' disparities from the maps given (one or both, already
    /// checked): a view without one gets the other's warped to it. `None`
    /// when neither is given.
    pub fn from_maps(
        left_map: Option<FloatImage>,
        right_map: Option<FloatImage>,
        left: &RgbImage,
        right: &RgbImage,
    ) -> Result<Option<Disparities>, ExtrapolateError> {
        Ok(Some(match (left_map, right_map) {
            (Some(dl), Some(dr)) => Disparities {
                left: dl,
                right: dr,
            },
            (Some(dl), None) => {
                let dr = derive_other_view(left, &dl, Side::Right)?;
                Disparities {
                    left: dl,
                    right: dr,
                }
            }
            (None, Some(dr)) => {
                let dl = derive_other_view(right, &dr, Side::Left)?;
                Disparities {
                    left: dl,
                    right: dr,
                }
            }
            (None, None) => return Ok(None),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_core::formats::pfm::{Endian, write_pfm_grey};

    #[test]
    fn bad_disparity_files_are_named_with_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, map: &FloatImage| {
            let path = dir.path().join(name);
            write_pfm_grey(&path, map, Endian::Little).unwrap();
            path
        };
        let mut nan = FloatImage::from_pixel(4, 3, image::Luma([2.0]));
        nan.put_pixel(1, 1, image::Luma([f32::NAN]));
        nan.put_pixel(2, 1, image::Luma([-1.0]));
        let cases = [
            (
                write("nan.pfm", &nan),
                "nan.pfm: 2 NaN or negative disparities",
            ),
            (
                write("small.pfm", &FloatImage::new(2, 2)),
                "small.pfm: disparity is (2, 2) but the views are (4, 3)",
            ),
            (
                write(
                    "empty.pfm",
                    &FloatImage::from_pixel(4, 3, image::Luma([f32::INFINITY])),
                ),
                "empty.pfm: no valid disparity at all",
            ),
        ];
        for (path, expected) in cases {
            let err = load_disparity(&path, (4, 3)).unwrap_err().to_string();
            assert!(err.contains(expected), "{err}");
        }
    }

    #[test]
    fn one_file_gives_both_views_and_unknown_pixels_are_filled() {
        let dir = tempfile::tempdir().unwrap();
        let mut map = FloatImage::from_pixel(8, 2, image::Luma([1.0]));
        map.put_pixel(7, 0, image::Luma([f32::INFINITY]));
        let path = dir.path().join("d.pfm");
        write_pfm_grey(&path, &map, Endian::Little).unwrap();
        let view = RgbImage::from_pixel(8, 2, image::Rgb([50, 60, 70]));
        let both = Disparities::from_files(Some(&path), None, &view, &view)
            .unwrap()
            .unwrap();
        assert!(both.left.iter().all(|d| *d == 1.0), "{:?}", both.left);
        assert!(both.right.iter().all(|d| *d == 1.0), "{:?}", both.right);
        assert!(
            Disparities::from_files(None, None, &view, &view)
                .unwrap()
                .is_none()
        );
    }
}
