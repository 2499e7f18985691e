//! A set made from one photo, on disk: the photo, its depth (a file, or a
//! network's), and where each output goes, in sibling folders under the
//! output folder (`image_1/ID.png`, `mask_1/ID.png`… beside the photo's
//! own `image_{r+1}/ID.ext`). Processing a set reads the photo, turns its
//! depth into the virtual rig's disparity ([`virtual_disparity`]),
//! synthesises every other camera ([`Extrapolator::views_from_one`]) and
//! writes each file atomically, the photo's link last, so a set whose
//! files all exist is complete.

use std::path::{Path, PathBuf};

use mbs_core::FloatImage;
use mbs_core::atomic::link_or_copy;
use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_core::formats::read_float_map;
use mbs_core::formats::rgb::{read_colour_photo, write_mask_png, write_rgb_png};
use mbs_dataset::ground_truth::find_map;
use mbs_dataset::photos::Photo;
use mbs_infer::{DepthEstimator, DepthKind, DepthMap};
use mbs_viz::photo_set_sheet;

use crate::disparity::load_disparity;
use crate::mono::{Scaling, ViewLayout, virtual_disparity};
use crate::{ExtrapolateError, Extrapolator, ViewFiles};

/// Where the depth of the photos comes from.
pub enum DepthSource<'a> {
    /// A monocular depth network.
    Network(&'a dyn DepthEstimator),
    /// Each set's depth file, holding maps of this kind.
    Files(DepthKind),
}

/// The input and output files of one set made from a photo.
#[derive(Debug, Clone, PartialEq)]
pub struct PhotoSet {
    /// The photo's path, shown in progress and errors.
    pub name: String,
    /// The sample id in the manifest.
    pub id: String,
    /// The photo (camera `layout.reference`).
    pub photo: PathBuf,
    /// The photo's depth file, when depths come from files.
    pub depth_file: Option<PathBuf>,
    /// The cameras of the set.
    pub layout: ViewLayout,
    /// Output: camera `k`'s view (the photo's link at the reference).
    pub views: Vec<PathBuf>,
    /// Output: camera `k`'s mask of synthesised pixels (none at the
    /// reference).
    pub masks: Vec<Option<PathBuf>>,
    /// Output: the photo's disparity against the camera one baseline
    /// away (PFM), from which every view was synthesised.
    pub disparity: PathBuf,
    /// Output: the contact sheet, when asked for.
    pub preview: PathBuf,
}

/// The sets of `photos` written under `out` with the cameras of
/// `layout`; depth files (if any) found by id in `depth_dir`, or the one
/// `depth_file` for a single photo.
pub fn photo_sets(
    photos: &[Photo],
    out: &Path,
    layout: ViewLayout,
    depth_dir: Option<&Path>,
    depth_file: Option<&Path>,
) -> Vec<PhotoSet> {
    let reference = layout.reference;
    photos
        .iter()
        .map(|photo| {
            let id = &photo.id;
            let png = format!("{id}.png");
            let photo_name = match photo.path.extension().and_then(|e| e.to_str()) {
                Some(ext) => format!("{id}.{ext}"),
                None => id.clone(),
            };
            let views = (0..layout.views)
                .map(|k| {
                    let name = if k == reference { &photo_name } else { &png };
                    out.join(format!("image_{}", k + 1)).join(name)
                })
                .collect();
            let masks = (0..layout.views)
                .map(|k| (k != reference).then(|| out.join(format!("mask_{}", k + 1)).join(&png)))
                .collect();
            PhotoSet {
                name: photo.path.display().to_string(),
                id: id.clone(),
                photo: photo.path.clone(),
                depth_file: depth_file
                    .map(Path::to_path_buf)
                    .or_else(|| depth_dir.and_then(|dir| find_map(dir, id))),
                layout,
                views,
                masks,
                disparity: out
                    .join(format!("disparity_{}", reference + 1))
                    .join(format!("{id}.pfm")),
                preview: out.join("preview").join(&png),
            }
        })
        .collect()
}

impl PhotoSet {
    /// Every file the set is read from: the photo and its depth file.
    pub fn inputs(&self) -> Vec<&Path> {
        let mut inputs = vec![self.photo.as_path()];
        inputs.extend(self.depth_file.as_deref());
        inputs
    }

    /// Every output a processed set has (not the preview).
    fn outputs(&self) -> impl Iterator<Item = &Path> {
        self.views
            .iter()
            .chain(self.masks.iter().flatten())
            .chain([&self.disparity])
            .map(PathBuf::as_path)
    }

    /// Every file processing writes (the contact sheet too with
    /// `preview`), less the photo's place when it already is the photo
    /// (a link an earlier run made).
    pub fn written(&self, preview: bool) -> Vec<&Path> {
        let photo_place = &self.views[self.layout.reference];
        let kept = mbs_core::inputs::same_file(&self.photo, photo_place);
        let mut written: Vec<&Path> = self
            .outputs()
            .filter(|path| !(kept && *path == photo_place.as_path()))
            .collect();
        if preview {
            written.push(&self.preview);
        }
        written
    }

    /// Whether every output exists (with the preview, when asked for).
    pub fn is_done(&self, preview: bool) -> bool {
        self.outputs().all(Path::exists) && (!preview || self.preview.exists())
    }

    /// The set's files as a manifest entry; the ground truth it records is
    /// the disparity every view was synthesised from (reference against
    /// the next camera, or the previous one when the reference is last).
    pub fn files(&self) -> ViewFiles<'_> {
        let r = self.layout.reference;
        let partner = if r + 1 < self.layout.views {
            r + 1
        } else {
            r - 1
        };
        ViewFiles {
            id: &self.id,
            views: self.views.iter().map(PathBuf::as_path).collect(),
            real: r,
            masks: self.masks.iter().map(Option::as_deref).collect(),
            ground_truth: Some((r, partner, self.disparity.as_path(), 1.0)),
        }
    }

    /// The photo's depth map: its file's, or `source`'s network's.
    fn depth(
        &self,
        photo: &mbs_core::RgbImage,
        source: &DepthSource<'_>,
    ) -> Result<DepthMap, ExtrapolateError> {
        match (source, &self.depth_file) {
            (DepthSource::Network(network), _) => Ok(network.estimate(photo)?),
            (DepthSource::Files(kind), Some(file)) => {
                let values = match kind {
                    DepthKind::Disparity => load_disparity(file, photo.dimensions())?,
                    _ => read_sized(file, photo.dimensions())?,
                };
                Ok(DepthMap {
                    values,
                    kind: *kind,
                })
            }
            (DepthSource::Files(_), None) => Err(ExtrapolateError::input(
                &self.photo,
                "no depth file of this photo's id in the depth folder",
            )),
        }
    }

    /// Reads the photo and its depth, synthesises every other camera with
    /// `scaling` and writes every output, the contact sheet with
    /// `preview`. A depth file's problem names the file; a network's, the
    /// photo.
    pub fn process(
        &self,
        extrapolator: &Extrapolator,
        depth: &DepthSource<'_>,
        scaling: Scaling,
        preview: bool,
    ) -> Result<(), ExtrapolateError> {
        let photo = read_colour_photo(&self.photo)?;
        let map = self.depth(&photo, depth)?;
        let named = self.depth_file.as_deref().unwrap_or(&self.photo);
        let disparity = virtual_disparity(&map.values, map.kind, scaling, &self.id)
            .map_err(|e| ExtrapolateError::input(named, e.to_string()))?;
        let set = extrapolator.views_from_one(&photo, &disparity.map, self.layout)?;
        for ((view, mask), new) in self.views.iter().zip(&self.masks).zip(&set.views) {
            if let (Some(mask), Some(new)) = (mask, new) {
                write_mask_png(mask, &new.mask)?;
                write_rgb_png(view, &new.image)?;
            }
        }
        if preview {
            let views: Vec<&mbs_core::RgbImage> = set
                .views
                .iter()
                .map(|new| new.as_ref().map_or(&photo, |v| &v.image))
                .collect();
            let sheet =
                photo_set_sheet(&views, self.layout.reference, &set.masks(), &disparity.map)?;
            write_rgb_png(&self.preview, &sheet)?;
        }
        write_pfm_grey(&self.disparity, &disparity.map, Endian::Little)?;
        link_or_copy(&self.photo, &self.views[self.layout.reference])?;
        Ok(())
    }
}

/// A float map from `file` that must be of `size` (width, height).
fn read_sized(file: &Path, size: (u32, u32)) -> Result<FloatImage, ExtrapolateError> {
    let map = read_float_map(file)?;
    if map.dimensions() != size {
        return Err(ExtrapolateError::input(
            file,
            format!(
                "the depth map is {:?} but the photo is {size:?} (width, height)",
                map.dimensions()
            ),
        ));
    }
    Ok(map)
}
