//! A frame on disk: the input pair, its disparity files if any, and where
//! each output goes, for one pair (`OUT/image_1.png`…) or a KITTI folder
//! (sibling folders `image_1/`, `mask_1/`… beside `image_2/`). Processing a
//! frame reads, extrapolates and writes it, each file atomically.

use std::path::{Path, PathBuf};

use mbs_core::atomic::link_or_copy;
use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_core::formats::rgb::{read_rgb, write_mask_png, write_rgb_png};
use mbs_dataset::StereoPair;
use mbs_dataset::ground_truth::find_map;
use mbs_viz::extrapolation_sheet;

use crate::{Disparities, DisparitySource, ExtrapolateError, Extrapolator, ViewFiles};

/// The input and output files of one frame. The output folder holds a
/// complete four-view set: the input views (and ground truth) are linked
/// into it when they lie elsewhere, so its manifest names only files inside.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Shown in progress and errors: the left view's path or KITTI file name.
    pub name: String,
    /// The sample id in the manifest: the left view's file stem.
    pub id: String,
    /// The left input view (camera 2 of 4).
    pub left: PathBuf,
    /// The right input view (camera 3 of 4).
    pub right: PathBuf,
    /// Disparity file of the left view, if any.
    pub left_disparity: Option<PathBuf>,
    /// Disparity file of the right view, if any.
    pub right_disparity: Option<PathBuf>,
    /// Output: the new view left of the left view.
    pub image_1: PathBuf,
    /// Output: the left input view's place in the output folder.
    pub image_2: PathBuf,
    /// Output: the right input view's place in the output folder.
    pub image_3: PathBuf,
    /// Output: the new view right of the right view.
    pub image_4: PathBuf,
    /// Output: synthesised pixels of `image_1`.
    pub mask_1: PathBuf,
    /// Output: synthesised pixels of `image_4`.
    pub mask_4: PathBuf,
    /// Output: the left view's disparity used (PFM).
    pub disparity_2: PathBuf,
    /// Output: the right view's disparity used (PFM).
    pub disparity_3: PathBuf,
    /// Output: the contact sheet, when asked for.
    pub preview: PathBuf,
    /// KITTI ground truth of the left view and its place in the output
    /// folder, recorded in the manifest.
    pub ground_truth: Option<(PathBuf, PathBuf)>,
}

/// The one frame of a pair (its target right of its reference) written
/// into `out`; disparity files from `left_disparity`/`right_disparity`, or
/// found as `disparity_2.*` and `disparity_3.*` in `disparity_dir` (an
/// error if it has neither).
pub fn pair_frame(
    pair: &StereoPair,
    out: &Path,
    (left_disparity, right_disparity): (Option<PathBuf>, Option<PathBuf>),
    disparity_dir: Option<&Path>,
) -> Result<Frame, ExtrapolateError> {
    let (left_disparity, right_disparity) = match disparity_dir {
        Some(dir) => {
            let found = (find_map(dir, "disparity_2"), find_map(dir, "disparity_3"));
            if found.0.is_none() && found.1.is_none() {
                return Err(ExtrapolateError::input(
                    dir,
                    "no disparity_2 or disparity_3 file (.pfm, .png or .exr) in this folder",
                ));
            }
            found
        }
        None => (left_disparity, right_disparity),
    };
    let (left, right) = (&pair.reference, &pair.target);
    let id = Some(pair.id.as_str())
        .filter(|s| mbs_core::confine::check_name(s).is_ok())
        .unwrap_or("pair")
        .to_string();
    Ok(Frame {
        name: left.display().to_string(),
        id,
        left: left.to_path_buf(),
        right: right.to_path_buf(),
        left_disparity,
        right_disparity,
        image_1: out.join("image_1.png"),
        image_2: out.join(linked_name("image_2", left)),
        image_3: out.join(linked_name("image_3", right)),
        image_4: out.join("image_4.png"),
        mask_1: out.join("mask_1.png"),
        mask_4: out.join("mask_4.png"),
        disparity_2: out.join("disparity_2.pfm"),
        disparity_3: out.join("disparity_3.pfm"),
        preview: out.join("preview.png"),
        ground_truth: None,
    })
}

/// `stem` with the extension of `input`, the name its link in the output
/// folder gets (the content is the input's, so is its format).
fn linked_name(stem: &str, input: &Path) -> String {
    match input.extension().and_then(|e| e.to_str()) {
        Some(ext) => format!("{stem}.{ext}"),
        None => stem.to_string(),
    }
}

/// The frames of a KITTI split folder's pairs (2015 or 2012, training or
/// testing): outputs in sibling folders under `out`, disparities found by
/// frame name in the folders given (a view without a file gets none).
pub fn kitti_frames(
    pairs: &[StereoPair],
    out: &Path,
    (left_dir, right_dir): (Option<&Path>, Option<&Path>),
) -> Vec<Frame> {
    pairs
        .iter()
        .map(|pair| {
            let stem = &pair.id;
            let name = format!("{stem}.png");
            Frame {
                left: pair.reference.clone(),
                right: pair.target.clone(),
                left_disparity: left_dir.and_then(|d| find_map(d, stem)),
                right_disparity: right_dir.and_then(|d| find_map(d, stem)),
                id: stem.clone(),
                image_1: out.join("image_1").join(&name),
                image_2: out.join("image_2").join(&name),
                image_3: out.join("image_3").join(&name),
                image_4: out.join("image_4").join(&name),
                mask_1: out.join("mask_1").join(&name),
                mask_4: out.join("mask_4").join(&name),
                disparity_2: out.join("disparity_2").join(format!("{stem}.pfm")),
                disparity_3: out.join("disparity_3").join(format!("{stem}.pfm")),
                preview: out.join("preview").join(&name),
                ground_truth: pair
                    .truth
                    .as_ref()
                    .map(|gt| (gt.disparity.clone(), out.join("disp_occ_0").join(&name))),
                name,
            }
        })
        .collect()
}

impl Frame {
    /// The eight files every processed frame has.
    pub fn outputs(&self) -> [&PathBuf; 8] {
        [
            &self.image_1,
            &self.image_2,
            &self.image_3,
            &self.image_4,
            &self.mask_1,
            &self.mask_4,
            &self.disparity_2,
            &self.disparity_3,
        ]
    }

    /// Every file the frame is read from: its views, disparity files and
    /// ground truth.
    pub fn inputs(&self) -> Vec<&Path> {
        let mut inputs = vec![self.left.as_path(), self.right.as_path()];
        inputs.extend(self.left_disparity.as_deref());
        inputs.extend(self.right_disparity.as_deref());
        inputs.extend(self.ground_truth.as_ref().map(|(truth, _)| truth.as_path()));
        inputs
    }

    /// Every file processing writes (the contact sheet too with
    /// `preview`): the outputs, less the places of the input views and
    /// ground truth that already are those inputs (a KITTI folder
    /// extrapolated in place, or the hard links an earlier run made), which
    /// are left as they are.
    pub fn written(&self, preview: bool) -> Vec<&Path> {
        let in_place = |input: &Path, place: &Path| mbs_core::inputs::same_file(input, place);
        let mut links = vec![(&self.left, &self.image_2), (&self.right, &self.image_3)];
        links.extend(
            self.ground_truth
                .as_ref()
                .map(|(truth, copy)| (truth, copy)),
        );
        let kept: Vec<&PathBuf> = links
            .into_iter()
            .filter(|(input, place)| in_place(input, place))
            .map(|(_, place)| place)
            .collect();
        let mut written: Vec<&Path> = self
            .outputs()
            .into_iter()
            .chain(self.ground_truth.as_ref().map(|(_, copy)| copy))
            .filter(|path| !kept.contains(path))
            .map(PathBuf::as_path)
            .collect();
        if preview {
            written.push(&self.preview);
        }
        written
    }

    /// Whether every output exists (with the preview, when asked for).
    pub fn is_done(&self, preview: bool) -> bool {
        self.outputs().iter().all(|p| p.exists()) && (!preview || self.preview.exists())
    }

    /// The frame's files as a manifest entry (its outputs need not exist).
    pub fn files(&self) -> ViewFiles<'_> {
        ViewFiles {
            id: &self.id,
            views: [&self.image_1, &self.image_2, &self.image_3, &self.image_4]
                .map(PathBuf::as_path)
                .to_vec(),
            real: 1,
            masks: vec![Some(&self.mask_1), None, None, Some(&self.mask_4)]
                .into_iter()
                .map(|mask| mask.map(PathBuf::as_path))
                .collect(),
            ground_truth: self
                .ground_truth
                .as_ref()
                .map(|(_, copy)| (1, 2, copy.as_path(), 1.0)),
        }
    }

    /// Reads the pair, takes its disparities from the frame's files (else
    /// from `source`), extrapolates it and writes every output, and the
    /// contact sheet with `preview`. A frame without a disparity file and
    /// without a source is an error naming its left view.
    pub fn process(
        &self,
        extrapolator: &Extrapolator,
        source: Option<&DisparitySource>,
        preview: bool,
    ) -> Result<(), ExtrapolateError> {
        let left = read_rgb(&self.left)?;
        let right = read_rgb(&self.right)?;
        if left.dimensions() != right.dimensions() {
            return Err(ExtrapolateError::input(
                &self.left,
                format!(
                    "the left view is {:?} but the right view {} is {:?} (width, height): not a rectified pair",
                    left.dimensions(),
                    self.right.display(),
                    right.dimensions()
                ),
            ));
        }
        let from_files = Disparities::from_files(
            self.left_disparity.as_deref(),
            self.right_disparity.as_deref(),
            &left,
            &right,
        )?;
        let disparities = match (from_files, source) {
            (Some(d), _) => d,
            (None, Some(source)) => source.disparities(&left, &right)?,
            (None, None) => {
                return Err(ExtrapolateError::input(
                    &self.left,
                    "no disparity: no disparity file for either view and no disparity source",
                ));
            }
        };
        let views = extrapolator.extrapolate(&left, &right, &disparities)?;
        write_mask_png(&self.mask_1, &views.mask_1)?;
        write_rgb_png(&self.image_1, &views.image_1)?;
        write_mask_png(&self.mask_4, &views.mask_4)?;
        write_rgb_png(&self.image_4, &views.image_4)?;
        if preview {
            let sheet = extrapolation_sheet(
                [&views.image_1, &left, &right, &views.image_4],
                [&views.mask_1, &views.mask_4],
                [&disparities.left, &disparities.right],
            )?;
            write_rgb_png(&self.preview, &sheet)?;
        }
        write_pfm_grey(&self.disparity_2, &disparities.left, Endian::Little)?;
        write_pfm_grey(&self.disparity_3, &disparities.right, Endian::Little)?;
        link_or_copy(&self.left, &self.image_2)?;
        link_or_copy(&self.right, &self.image_3)?;
        if let Some((truth, copy)) = &self.ground_truth {
            link_or_copy(truth, copy)?;
        }
        Ok(())
    }
}
