//! The manifest of synthesised sets: a rig of uniformly spaced cameras whose
//! views are the real ones and the synthesised ones, the synthesised views
//! carrying their masks. Extrapolated pairs are four cameras (image_1 new at
//! -B, the input pair image_2 and image_3, image_4 new at +2B); a set from
//! one image has the image at its reference camera and every other view
//! synthesised.

use std::collections::BTreeMap;
use std::path::Path;

use mbs_core::Rig;
use mbs_dataset::manifest::{FORMAT, Manifest, PairGroundTruth, Provenance, Sample, Split};
use mbs_dataset::probe::probe;

use crate::ExtrapolateError;

/// The files of one set.
pub struct ViewFiles<'a> {
    /// Sample id.
    pub id: &'a str,
    /// Camera `k`'s view.
    pub views: Vec<&'a Path>,
    /// The camera whose view is real: its size is the sample's.
    pub real: usize,
    /// Camera `k`'s mask of synthesised pixels, `None` for a real view.
    pub masks: Vec<Option<&'a Path>>,
    /// A disparity map of camera `reference` against camera `target`
    /// (reference, target, file, scale to that pair), if any.
    pub ground_truth: Option<(usize, usize, &'a Path, f64)>,
}

/// The name, rig and provenance a manifest of sets records.
pub struct SetKind {
    /// The manifest's name.
    pub name: &'static str,
    /// Focal length in pixels.
    pub focal: f64,
    /// Baseline between adjacent cameras in metres.
    pub baseline: f64,
    /// The tool and its settings.
    pub provenance: Provenance,
}

/// `path` as a manifest name relative to the folder `out`, which must
/// hold it (see [`mbs_core::confine`]).
fn relative(out: &Path, path: &Path) -> Result<String, ExtrapolateError> {
    let absolute =
        |p: &Path| std::path::absolute(p).map_err(|e| ExtrapolateError::input(p, e.to_string()));
    mbs_core::confine::name_inside(&absolute(out)?, &absolute(path)?).ok_or_else(|| {
        ExtrapolateError::input(path, format!("is not a file name inside {}", out.display()))
    })
}

/// The manifest of `sets`, to be saved in `out`, on a rig of as many
/// cameras as the first set has views. Image sizes come from the real
/// views' headers; sets of another size than the first record their own
/// `image_size`.
pub fn views_manifest(
    sets: &[ViewFiles<'_>],
    out: &Path,
    kind: SetKind,
) -> Result<Manifest, ExtrapolateError> {
    let cameras = sets.first().map_or(4, |set| set.views.len());
    let mut rig: Option<Rig> = None;
    let mut samples = Vec::with_capacity(sets.len());
    for set in sets {
        let real = set.views[set.real];
        let info = probe(real, false).map_err(|e| ExtrapolateError::input(real, e.to_string()))?;
        let size = (info.width, info.height);
        let rig = *rig.get_or_insert_with(|| {
            Rig::centred(cameras, kind.baseline, kind.focal, size.0, size.1)
        });
        let views = set
            .views
            .iter()
            .map(|v| relative(out, v))
            .collect::<Result<Vec<_>, _>>()?;
        let ground_truth = match set.ground_truth {
            Some((reference, target, file, scale)) => vec![PairGroundTruth {
                reference,
                target,
                disparity: relative(out, file)?,
                scale,
                occlusion: None,
            }],
            None => Vec::new(),
        };
        let synthesized_masks = set
            .masks
            .iter()
            .map(|mask| mask.map(|m| relative(out, m)).transpose())
            .collect::<Result<Vec<_>, _>>()?;
        samples.push(Sample {
            id: set.id.to_string(),
            split: Split::Train,
            town: None,
            weather: None,
            sequence: None,
            views,
            depth: None,
            ground_truth,
            synthesized_masks,
            sha256: BTreeMap::new(),
            image_size: (size != (rig.width, rig.height)).then_some(size),
        });
    }
    Ok(Manifest {
        format: FORMAT.into(),
        name: kind.name.into(),
        rig: rig.unwrap_or_else(|| Rig::centred(cameras, kind.baseline, kind.focal, 1, 1)),
        depth: None,
        samples,
        provenance: Some(kind.provenance),
    })
}

/// The manifest of extrapolated pairs (`sets` of four views), to be saved
/// in `out`.
pub fn four_view_manifest(
    sets: &[ViewFiles<'_>],
    out: &Path,
    focal: f64,
    baseline: f64,
) -> Result<Manifest, ExtrapolateError> {
    let kind = SetKind {
        name: "extrapolated",
        focal,
        baseline,
        provenance: Provenance {
            tool: "mbs-tool extrapolate".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            settings: serde_json::json!({ "focal_px": focal, "baseline_m": baseline }),
        },
    };
    views_manifest(sets, out, kind)
}
