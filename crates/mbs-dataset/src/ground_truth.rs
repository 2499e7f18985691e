//! Pairs with ground-truth disparity, from a manifest or a KITTI training
//! folder, in one form: the two views, the side of the target, the GT file
//! with its scale, and where the non-occluded pixels are. Loading gives the
//! disparity in pixels and the non-occluded mask. `eval`, `predict
//! --manifest` and the trainer's validation all list their pairs here.

use std::path::{Path, PathBuf};

use mbs_core::formats::{read_disparity, rgb::read_mask};
use mbs_core::metrics::valid_mask;
use mbs_core::{FloatImage, MaskImage, Side};

use crate::DatasetError;
use crate::kitti::{KittiVersion, png_stems};
use crate::manifest::{Manifest, Sample, Split, resolve};

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

/// One pair with ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundTruthPair {
    /// The sample id (manifests) or frame name (KITTI, e.g. `000000_10`).
    pub id: String,
    /// Camera indices of the reference and target (KITTI: 0 and 1).
    pub cameras: (usize, usize),
    /// The reference view.
    pub reference: PathBuf,
    /// The target view.
    pub target: PathBuf,
    /// Which side of the reference the target lies on.
    pub side: Side,
    /// The reference view's ground truth.
    pub truth: GroundTruthFile,
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
    pub fn load(&self, png_scale: Option<f32>) -> Result<GroundTruth, DatasetError> {
        let mut map = read_disparity(&self.disparity, png_scale)?;
        if self.scale != 1.0 {
            map.iter_mut().for_each(|d| *d *= self.scale);
        }
        let noc = match &self.noc {
            None => None,
            Some(NocSource::Map(p)) => Some(valid_mask(&read_disparity(p, png_scale)?)),
            Some(NocSource::Mask(p)) => Some(read_mask(p)?),
            Some(NocSource::Occlusion(p)) => {
                let mut mask = read_mask(p)?;
                mask.iter_mut()
                    .for_each(|v| *v = if *v == 0 { 255 } else { 0 });
                Some(mask)
            }
        };
        Ok(GroundTruth {
            disparity: map,
            noc,
        })
    }
}

/// The view `k` of `sample`, resolved against the manifest's folder.
pub fn sample_view(path: &Path, sample: &Sample, k: usize) -> Result<PathBuf, DatasetError> {
    sample
        .views
        .get(k)
        .map(|v| resolve(path, v))
        .ok_or_else(|| DatasetError::Manifest {
            path: path.to_path_buf(),
            message: format!("sample {} has no view {k}", sample.id),
        })
}

/// The pairs `cameras` of `sample` that have ground truth, in the order of
/// `cameras` (a pair without ground truth is left out). `path` is the
/// manifest's file, which relative paths are resolved against.
pub fn sample_pairs(
    path: &Path,
    sample: &Sample,
    cameras: &[(usize, usize)],
) -> Result<Vec<GroundTruthPair>, DatasetError> {
    let mut pairs = Vec::new();
    for &(reference, target) in cameras {
        let Some(gt) = sample
            .ground_truth
            .iter()
            .find(|g| g.reference == reference && g.target == target)
        else {
            continue;
        };
        pairs.push(GroundTruthPair {
            id: sample.id.clone(),
            cameras: (reference, target),
            reference: sample_view(path, sample, reference)?,
            target: sample_view(path, sample, target)?,
            side: if target > reference {
                Side::Right
            } else {
                Side::Left
            },
            truth: GroundTruthFile {
                disparity: resolve(path, &gt.disparity),
                scale: gt.scale as f32,
                noc: gt
                    .occlusion
                    .as_deref()
                    .map(|o| NocSource::Occlusion(resolve(path, o))),
            },
        });
    }
    Ok(pairs)
}

/// The pairs `cameras` with ground truth of every sample of `split` (all
/// samples for `None`) of the manifest `manifest` read from `path`, sample
/// by sample. A camera outside the rig is an error.
pub fn manifest_pairs(
    path: &Path,
    manifest: &Manifest,
    cameras: &[(usize, usize)],
    split: Option<Split>,
) -> Result<Vec<GroundTruthPair>, DatasetError> {
    check_cameras(path, manifest, cameras)?;
    let mut pairs = Vec::new();
    for sample in manifest
        .samples
        .iter()
        .filter(|s| split.is_none_or(|split| s.split == split))
    {
        pairs.extend(sample_pairs(path, sample, cameras)?);
    }
    Ok(pairs)
}

/// Refuses camera pairs that do not fit the manifest's rig.
pub fn check_cameras(
    path: &Path,
    manifest: &Manifest,
    cameras: &[(usize, usize)],
) -> Result<(), DatasetError> {
    let views = manifest.rig.num_views;
    match cameras
        .iter()
        .find(|&&(r, t)| r >= views || t >= views || r == t)
    {
        Some((r, t)) => Err(DatasetError::Manifest {
            path: path.to_path_buf(),
            message: format!("pair {r}:{t} does not fit the rig's {views} cameras"),
        }),
        None => Ok(()),
    }
}

/// The frames of a KITTI 2015 (`disp_occ_0`, `disp_noc_0`) or 2012
/// (`disp_occ`, `disp_noc`) training folder that have ground truth, sorted
/// by name. The views' paths are where KITTI keeps them; they are not
/// checked, so a folder of ground truth alone can score predictions.
pub fn kitti_pairs(dir: &Path) -> Result<Vec<GroundTruthPair>, DatasetError> {
    let (version, occ, noc) = [KittiVersion::Kitti2015, KittiVersion::Kitti2012]
        .into_iter()
        .map(|v| (v, dir.join(v.gt_dirs().0), dir.join(v.gt_dirs().1)))
        .find(|(_, o, _)| o.is_dir())
        .ok_or_else(|| DatasetError::Layout {
            path: dir.to_path_buf(),
            message: "no KITTI ground truth (expected disp_occ_0 or disp_occ)".into(),
        })?;
    let names = png_stems(&occ)?;
    if names.is_empty() {
        return Err(DatasetError::Layout {
            path: occ,
            message: "no ground-truth PNGs".into(),
        });
    }
    let (left, right) = version.view_dirs();
    Ok(names
        .into_iter()
        .map(|stem| {
            let file = format!("{stem}.png");
            let noc_map = noc.join(&file);
            GroundTruthPair {
                cameras: (0, 1),
                reference: dir.join(left).join(&file),
                target: dir.join(right).join(&file),
                side: Side::Right,
                truth: GroundTruthFile {
                    disparity: occ.join(&file),
                    scale: 1.0,
                    noc: noc_map.is_file().then_some(NocSource::Map(noc_map)),
                },
                id: stem,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::touch;
    use mbs_core::formats::pfm::{Endian, write_pfm_grey};
    use mbs_core::formats::rgb::write_mask_png;

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
    fn kitti_pairs_list_ground_truth_with_noc_maps_where_present() {
        let dir = tempfile::tempdir().unwrap();
        touch(&dir.path().join("disp_occ_0/000001_10.png"));
        touch(&dir.path().join("disp_occ_0/000000_10.png"));
        touch(&dir.path().join("disp_noc_0/000001_10.png"));
        let pairs = kitti_pairs(dir.path()).unwrap();
        let ids: Vec<&str> = pairs.iter().map(|p| p.id.as_str()).collect();
        assert_eq!(ids, ["000000_10", "000001_10"]);
        assert_eq!(pairs[0].truth.noc, None);
        assert_eq!(
            pairs[1].truth.noc,
            Some(NocSource::Map(dir.path().join("disp_noc_0/000001_10.png")))
        );
        assert_eq!(pairs[1].reference, dir.path().join("image_2/000001_10.png"));
        let err = kitti_pairs(&dir.path().join("image_2")).unwrap_err();
        assert!(err.to_string().contains("expected disp_occ_0"), "{err}");
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
}
