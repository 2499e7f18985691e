//! The manifest of extrapolated pairs: a 4-camera rig with uniform baseline,
//! image_1 (new, at -B), the input pair (image_2, image_3), image_4 (new, at
//! +2B); the synthesised views carry their masks.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use mbs_core::Rig;
use mbs_dataset::manifest::{FORMAT, Manifest, PairGroundTruth, Provenance, Sample, Split};
use mbs_dataset::probe::probe;

use crate::ExtrapolateError;

/// The files of one extrapolated frame.
pub struct FourViewFiles<'a> {
    /// Sample id (the frame's name).
    pub id: &'a str,
    /// image_1, image_2, image_3, image_4.
    pub views: [&'a PathBuf; 4],
    /// Synthesised-pixel masks of image_1 and image_4.
    pub masks: [&'a PathBuf; 2],
    /// Ground-truth disparity of image_2 against image_3, if any.
    pub ground_truth: Option<&'a Path>,
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

/// The manifest of `frames`, to be saved in `out`. Image sizes come from
/// the left views' headers; frames of another size than the first record
/// their own `image_size`.
pub fn four_view_manifest(
    frames: &[FourViewFiles<'_>],
    out: &Path,
    focal: f64,
    baseline: f64,
) -> Result<Manifest, ExtrapolateError> {
    let mut rig: Option<Rig> = None;
    let mut samples = Vec::with_capacity(frames.len());
    for frame in frames {
        let info = probe(frame.views[1], false)
            .map_err(|e| ExtrapolateError::input(frame.views[1], e.to_string()))?;
        let size = (info.width, info.height);
        let rig = *rig.get_or_insert_with(|| Rig::centred(4, baseline, focal, size.0, size.1));
        let views = frame
            .views
            .iter()
            .map(|v| relative(out, v))
            .collect::<Result<Vec<_>, _>>()?;
        let ground_truth = match frame.ground_truth {
            Some(gt) => vec![PairGroundTruth {
                reference: 1,
                target: 2,
                disparity: relative(out, gt)?,
                scale: 1.0,
                occlusion: None,
            }],
            None => Vec::new(),
        };
        samples.push(Sample {
            id: frame.id.to_string(),
            split: Split::Train,
            town: None,
            weather: None,
            sequence: None,
            views,
            depth: None,
            ground_truth,
            synthesized_masks: vec![
                Some(relative(out, frame.masks[0])?),
                None,
                None,
                Some(relative(out, frame.masks[1])?),
            ],
            sha256: BTreeMap::new(),
            image_size: (size != (rig.width, rig.height)).then_some(size),
        });
    }
    Ok(Manifest {
        format: FORMAT.into(),
        name: "extrapolated".into(),
        rig: rig.unwrap_or_else(|| Rig::centred(4, baseline, focal, 1, 1)),
        depth: None,
        samples,
        provenance: Some(Provenance {
            tool: "mbs-tool extrapolate".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            settings: serde_json::json!({ "focal_px": focal, "baseline_m": baseline }),
        }),
    })
}
