//! The training samples of a manifest: the views of every `train` sample,
//! resolved to files, with the rig that relates them.

use std::path::{Path, PathBuf};

use mbs_core::Rig;
use mbs_dataset::Manifest;
use mbs_dataset::manifest::{Split, resolve};
use mbs_dataset::probe::probe;

use crate::error::BatchError;

/// The views of one sample, left to right.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewPaths {
    /// The sample's id.
    pub id: String,
    /// One image per camera.
    pub views: Vec<PathBuf>,
    /// `(width, height)` of the images.
    pub size: (u32, u32),
}

/// Every training sample of a manifest.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainingSamples {
    /// The camera rig (positions give the baseline ratios).
    pub rig: Rig,
    /// The samples of the `train` split.
    pub samples: Vec<ViewPaths>,
}

impl TrainingSamples {
    /// The `train` samples of the manifest at `path`; every one must have
    /// one view per camera and images at least `crop` (height, width).
    pub fn load(path: &Path, crop: (usize, usize)) -> Result<Self, BatchError> {
        let manifest = Manifest::load(path)?;
        Self::from_manifest(path, &manifest, crop)
    }

    /// As [`TrainingSamples::load`] on a manifest already read from `path`.
    pub fn from_manifest(
        path: &Path,
        manifest: &Manifest,
        (crop_height, crop_width): (usize, usize),
    ) -> Result<Self, BatchError> {
        let rig = manifest.rig;
        if rig.num_views < 2 {
            return Err(BatchError::data(
                path,
                format!(
                    "the rig has {} camera(s); S3 needs at least 2",
                    rig.num_views
                ),
            ));
        }
        let mut samples = Vec::new();
        for sample in manifest.samples.iter().filter(|s| s.split == Split::Train) {
            if sample.views.len() != rig.num_views {
                return Err(BatchError::data(
                    path,
                    format!(
                        "sample {} has {} views for a {}-camera rig",
                        sample.id,
                        sample.views.len(),
                        rig.num_views
                    ),
                ));
            }
            let size = sample.size(&rig);
            if (size.1 as usize) < crop_height || (size.0 as usize) < crop_width {
                return Err(BatchError::data(
                    path,
                    format!(
                        "sample {} is {}x{} (height x width), smaller than the {crop_height}x{crop_width} crop; choose a smaller crop",
                        sample.id, size.1, size.0
                    ),
                ));
            }
            samples.push(ViewPaths {
                id: sample.id.clone(),
                views: sample.views.iter().map(|v| resolve(path, v)).collect(),
                size,
            });
        }
        if samples.is_empty() {
            return Err(BatchError::data(path, "no sample of the `train` split"));
        }
        Ok(Self { rig, samples })
    }
}

impl TrainingSamples {
    /// Checks every view's header (size and completeness, as `validate`
    /// does without `--deep`) before training starts, so a bad file does
    /// not end a run hours in; the error lists the problems found.
    pub fn check_files(&self, manifest: &Path) -> Result<(), BatchError> {
        use rayon::prelude::*;
        let problems: Vec<String> = self
            .samples
            .par_iter()
            .flat_map_iter(|sample| {
                sample.views.iter().filter_map(move |view| {
                    let problem = match probe(view, false) {
                        Err(e) => e.to_string(),
                        Ok(info) if (info.width, info.height) != sample.size => format!(
                            "image is {}x{}, the manifest says {}x{}",
                            info.width, info.height, sample.size.0, sample.size.1
                        ),
                        Ok(_) => return None,
                    };
                    Some(format!(
                        "sample {}: {}: {problem}",
                        sample.id,
                        view.display()
                    ))
                })
            })
            .collect();
        if problems.is_empty() {
            return Ok(());
        }
        const SHOWN: usize = 10;
        let mut message = format!(
            "{} training view(s) cannot be used (`mbs-tool validate` checks them all):",
            problems.len()
        );
        for line in problems.iter().take(SHOWN) {
            message.push_str(&format!("\n  {line}"));
        }
        if problems.len() > SHOWN {
            message.push_str(&format!("\n  … and {} more", problems.len() - SHOWN));
        }
        Err(BatchError::data(manifest, message))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A FIFO given as a training view is named at once by the check
    /// before training (its header is read through a handle opened without
    /// blocking), with the sample, the path and what it is.
    #[cfg(unix)]
    #[test]
    fn a_fifo_view_is_named_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let image = image::RgbImage::new(8, 4);
        let views: Vec<PathBuf> = (0..3)
            .map(|v| dir.path().join(format!("v{v}.png")))
            .collect();
        image.save(&views[0]).unwrap();
        image.save(&views[2]).unwrap();
        let made = std::process::Command::new("mkfifo")
            .arg(&views[1])
            .status()
            .unwrap();
        assert!(made.success(), "mkfifo {}", views[1].display());
        let samples = TrainingSamples {
            rig: Rig::centred(3, 0.1, 100.0, 8, 4),
            samples: vec![ViewPaths {
                id: "s0".into(),
                views: views.clone(),
                size: (8, 4),
            }],
        };
        let manifest = dir.path().join("manifest.json");
        let (done, outcome) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            done.send(samples.check_files(&manifest).map_err(|e| e.to_string()))
        });
        let err = outcome
            .recv_timeout(std::time::Duration::from_secs(10))
            .expect("checking a FIFO view blocked")
            .unwrap_err();
        let named = format!("sample s0: {}: ", views[1].display());
        assert!(err.contains(&named) && err.contains("a FIFO"), "{err}");
        assert!(err.contains("1 training view(s) cannot be used"), "{err}");
    }
}
