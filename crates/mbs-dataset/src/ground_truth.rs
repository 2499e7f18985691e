//! Ground-truth disparity files: the file with its scale and where the
//! non-occluded pixels are; loading gives the disparity in pixels and the
//! non-occluded mask. The pairs they belong to are listed by [`crate::pairs`].

use std::io::ErrorKind;
use std::path::{Path, PathBuf};

use mbs_core::FormatError;
use mbs_core::formats::{read_disparity, rgb::read_mask};
use mbs_core::{FloatImage, MaskImage};

use crate::DatasetError;

/// The extensions a disparity map is looked up by, in order.
pub const MAP_EXTENSIONS: [&str; 3] = ["pfm", "png", "exr"];

/// `dir/stem.pfm`, `.png` or `.exr`: the first that is a file.
pub fn find_map(dir: &Path, stem: &str) -> Option<PathBuf> {
    MAP_EXTENSIONS
        .iter()
        .map(|ext| dir.join(format!("{stem}.{ext}")))
        .find(|p| p.is_file())
}

/// Where the non-occluded pixels of a pair are.
#[derive(Debug, Clone, PartialEq)]
pub enum NocSource {
    /// A non-occluded GT map (KITTI `disp_noc`): valid = non-occluded.
    Map(PathBuf),
    /// A mask, non-zero = non-occluded (Middlebury `nonocc.png`).
    Mask(PathBuf),
    /// A mask, non-zero = occluded (manifests' `occlusion`).
    Occlusion(PathBuf),
    /// A mask of levels: 255 = non-occluded, 128 = occluded, 0 = no ground
    /// truth (Middlebury 2014's and ETH3D's `mask0nocc.png`).
    Levels(PathBuf),
}

impl NocSource {
    /// The file it is read from.
    pub fn path(&self) -> &Path {
        match self {
            NocSource::Map(path)
            | NocSource::Mask(path)
            | NocSource::Occlusion(path)
            | NocSource::Levels(path) => path,
        }
    }
}

/// A ground-truth disparity file with what it takes to read it.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundTruthFile {
    /// The ground-truth disparity file.
    pub disparity: PathBuf,
    /// The pair's disparity is this times the file's values (manifests
    /// share one-baseline files between pairs).
    pub scale: f32,
    /// Where the non-occluded pixels are, if known.
    pub noc: Option<NocSource>,
}

/// A pair's ground truth in memory.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundTruth {
    /// Disparity in pixels, `+inf` where unknown.
    pub disparity: FloatImage,
    /// Non-occluded mask (non-zero = visible in the target), if known.
    pub noc: Option<MaskImage>,
}

impl GroundTruthFile {
    /// Reads the disparity times `scale` (`png_scale`: codes per pixel of
    /// integer files, see [`read_disparity`]) with its non-occluded mask.
    /// A mask that is missing or cannot be read is an error naming it:
    /// scoring the frame without it would leave it out of NOC and OCC.
    pub fn load(&self, png_scale: Option<f32>) -> Result<GroundTruth, DatasetError> {
        let mut map = read_disparity(&self.disparity, png_scale)?;
        if self.scale != 1.0 {
            map.iter_mut().for_each(|d| *d *= self.scale);
        }
        let noc = match &self.noc {
            None => None,
            Some(source) => Some(source.read(png_scale).map_err(|e| match e {
                FormatError::Io { path, source } if source.kind() == ErrorKind::NotFound => {
                    DatasetError::Layout {
                        path,
                        message: format!(
                            "no such file: the non-occluded pixels of {} (without them NOC \
                             and OCC would leave this frame out)",
                            self.disparity.display()
                        ),
                    }
                }
                e => e.into(),
            })?),
        };
        Ok(GroundTruth {
            disparity: map,
            noc,
        })
    }
}

impl NocSource {
    /// The mask of non-occluded pixels (non-zero) read from the file.
    fn read(&self, png_scale: Option<f32>) -> Result<MaskImage, FormatError> {
        Ok(match self {
            NocSource::Map(p) => valid_mask(&read_disparity(p, png_scale)?),
            NocSource::Mask(p) => read_mask(p)?,
            NocSource::Levels(p) => {
                let mut mask = read_mask(p)?;
                mask.iter_mut()
                    .for_each(|v| *v = if *v == 255 { 255 } else { 0 });
                mask
            }
            NocSource::Occlusion(p) => {
                let mut mask = read_mask(p)?;
                mask.iter_mut()
                    .for_each(|v| *v = if *v == 0 { 255 } else { 0 });
                mask
            }
        })
    }
}

/// The non-occluded mask implied by a non-occluded GT map (KITTI
/// `disp_noc`): set where the map is finite.
fn valid_mask(map: &FloatImage) -> MaskImage {
    let data = map
        .as_raw()
        .iter()
        .map(|v| if v.is_finite() { 255 } else { 0 })
        .collect();
    // One sample per pixel in both images, so the length matches.
    MaskImage::from_raw(map.width(), map.height(), data).expect("same size as the map")
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_core::formats::pfm::{Endian, write_pfm_grey};
    use mbs_core::formats::rgb::write_mask_png;
    use mbs_test_support::files::touch;

    #[test]
    fn maps_are_found_pfm_then_png_then_exr() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(find_map(dir.path(), "a"), None);
        touch(&dir.path().join("a.exr"));
        assert_eq!(find_map(dir.path(), "a"), Some(dir.path().join("a.exr")));
        touch(&dir.path().join("a.png"));
        assert_eq!(find_map(dir.path(), "a"), Some(dir.path().join("a.png")));
        touch(&dir.path().join("a.pfm"));
        assert_eq!(find_map(dir.path(), "a"), Some(dir.path().join("a.pfm")));
    }

    #[test]
    fn loading_scales_the_map_and_inverts_occlusion_masks() {
        let dir = tempfile::tempdir().unwrap();
        let gt = dir.path().join("gt.pfm");
        write_pfm_grey(
            &gt,
            &FloatImage::from_raw(2, 1, vec![1.5, f32::INFINITY]).unwrap(),
            Endian::Little,
        )
        .unwrap();
        let occ = dir.path().join("occ.png");
        write_mask_png(&occ, &MaskImage::from_raw(2, 1, vec![255, 0]).unwrap()).unwrap();
        let file = |scale, noc| GroundTruthFile {
            disparity: gt.clone(),
            scale,
            noc: Some(noc),
        };
        let loaded = file(2.0, NocSource::Occlusion(occ.clone()))
            .load(None)
            .unwrap();
        assert_eq!(loaded.disparity.as_raw(), &vec![3.0, f32::INFINITY]);
        assert_eq!(loaded.noc.unwrap().as_raw(), &vec![0, 255]);
        let mask = file(1.0, NocSource::Mask(occ)).load(None).unwrap();
        assert_eq!(mask.noc.unwrap().as_raw(), &vec![255, 0]);
    }

    #[test]
    fn valid_mask_marks_finite_pixels() {
        let map = FloatImage::from_raw(3, 1, vec![1.0, f32::INFINITY, f32::NAN]).unwrap();
        assert_eq!(valid_mask(&map).as_raw(), &vec![255, 0, 0]);
    }
}
