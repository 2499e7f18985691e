//! Extrapolation measured on real multi-view scenes: every pair
//! `(k, k + step)` of equally spaced views with a real view one baseline
//! beyond each side is extrapolated, and the new views are scored against
//! views `k - step` and `k + 2 step` (PSNR and SSIM over all pixels, and
//! over the synthesised pixels: those the mask marks, holes and dilated
//! pixels). `step` 1 is adjacent views; 2 doubles the disparities.

use std::path::{Path, PathBuf};

use mbs_core::formats::rgb::read_rgb;
use mbs_core::{MaskImage, RgbImage};
use mbs_image::quality::{psnr, ssim};

use crate::{DisparitySource, ExtrapolateError, Extrapolator};

/// A scene of equally spaced views on one horizontal line, left to right.
pub struct Scene {
    /// Its name in reports.
    pub name: String,
    /// The views, leftmost first.
    pub views: Vec<RgbImage>,
}

impl Scene {
    /// Reads the views at `paths` (leftmost first), all of one size.
    pub fn load(name: &str, paths: &[PathBuf]) -> Result<Scene, ExtrapolateError> {
        let views = paths
            .iter()
            .map(|p| read_rgb(p))
            .collect::<Result<Vec<_>, _>>()?;
        if let Some((path, view)) = paths
            .iter()
            .zip(&views)
            .find(|(_, v)| v.dimensions() != views[0].dimensions())
        {
            return Err(ExtrapolateError::input(
                path,
                format!(
                    "is {:?}, the first view of {name} {:?} (width, height)",
                    view.dimensions(),
                    views[0].dimensions()
                ),
            ));
        }
        Ok(Scene {
            name: name.to_string(),
            views,
        })
    }

    /// The scene with `offset` px added to the disparity of every view
    /// step: view `k` (of `n`) keeps its columns `k * offset ..` for a
    /// width of `width - (n - 1) * offset`. For rigs whose disparities go
    /// negative (cameras converged on a focus plane, as in light-field
    /// data), since the pipeline takes disparity as a non-negative
    /// magnitude.
    pub fn with_disparity_offset(self, offset: u32) -> Result<Scene, ExtrapolateError> {
        let n = self.views.len() as u32;
        let (width, height) = self.views.first().map_or((0, 0), |v| v.dimensions());
        let kept = n
            .checked_sub(1)
            .and_then(|steps| steps.checked_mul(offset))
            .and_then(|cut| width.checked_sub(cut))
            .filter(|w| *w > 0)
            .ok_or_else(|| {
                ExtrapolateError::input(
                    self.name.as_str(),
                    format!("a disparity offset of {offset} px leaves no column of {n} views {width} px wide"),
                )
            })?;
        let views = self
            .views
            .iter()
            .zip(0u32..)
            .map(|(view, k)| {
                image::imageops::crop_imm(view, k * offset, 0, kept, height).to_image()
            })
            .collect();
        Ok(Scene {
            name: self.name,
            views,
        })
    }

    /// The scenes shipped in a checkout's `testdata/`: Middlebury Tsukuba
    /// (5 views), Baby2, Bowling2 and Laundry (7 views each).
    pub fn shipped(testdata: &Path) -> Result<Vec<Scene>, ExtrapolateError> {
        let tsukuba = testdata.join("middlebury-tsukuba-row3");
        let mut scenes = vec![Scene::load(
            "Tsukuba",
            &(1..=5)
                .map(|k| tsukuba.join(format!("scene1.row3.col{k}.ppm")))
                .collect::<Vec<_>>(),
        )?];
        for (name, folder) in [
            ("Baby2", "middlebury-baby2"),
            ("Bowling2", "middlebury-bowling2"),
            ("Laundry", "middlebury-laundry"),
        ] {
            let dir = testdata.join(folder);
            let paths: Vec<PathBuf> = (0..7).map(|k| dir.join(format!("view{k}.png"))).collect();
            scenes.push(Scene::load(name, &paths)?);
        }
        Ok(scenes)
    }
}

/// One new view of a scene and the real view it is scored against.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtrapolatedView {
    /// The input pair `(k, k + step)`.
    pub pair: (usize, usize),
    /// The index of the real view at the new view's position.
    pub target: usize,
    /// The new view.
    pub image: RgbImage,
    /// Its synthesised pixels (255): holes and dilation.
    pub mask: MaskImage,
}

/// Extrapolates every pair `(k, k + step)` of `scene` that has a real view
/// one baseline (`step` views) beyond each side, with disparities from
/// `source`: two new views per pair, at views `k - step` and `k + 2 step`.
pub fn extrapolate_scene(
    scene: &Scene,
    extrapolator: &Extrapolator,
    source: &DisparitySource,
    step: usize,
) -> Result<Vec<ExtrapolatedView>, ExtrapolateError> {
    let mut views = Vec::new();
    let step = step.max(1);
    for k in step..scene.views.len().saturating_sub(2 * step) {
        let (left, right) = (&scene.views[k], &scene.views[k + step]);
        let disparities = source.disparities(left, right)?;
        let new = extrapolator.extrapolate(left, right, &disparities)?;
        let pair = (k, k + step);
        views.push(ExtrapolatedView {
            pair,
            target: k - step,
            image: new.image_1,
            mask: new.mask_1,
        });
        views.push(ExtrapolatedView {
            pair,
            target: k + 2 * step,
            image: new.image_4,
            mask: new.mask_4,
        });
    }
    Ok(views)
}

/// The scores of one extrapolated view against the real one.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewScore {
    /// The scene.
    pub scene: String,
    /// The input pair `(k, k + step)`.
    pub pair: (usize, usize),
    /// The real view it is scored against (`k - step` or `k + 2 step`).
    pub target: usize,
    /// PSNR (dB) over all pixels.
    pub psnr_all: f64,
    /// SSIM over all pixels.
    pub ssim_all: f64,
    /// PSNR (dB) over the synthesised pixels, if there are any.
    pub psnr_synthesised: Option<f64>,
    /// Share of the view's pixels that were synthesised.
    pub synthesised: f64,
}

impl ViewScore {
    /// Scores `view` of `scene` against its real view, with the PSNR of
    /// synthesised pixels taken over `synthesised` (the view's own mask, or
    /// one shared by the pipelines being compared).
    pub fn of(
        scene: &Scene,
        view: &ExtrapolatedView,
        synthesised: &MaskImage,
    ) -> Result<ViewScore, ExtrapolateError> {
        let (k, j) = view.pair;
        let real = scene.views.get(view.target);
        let size_error = || {
            ExtrapolateError::input(
                scene.name.as_str(),
                format!(
                    "view {} is missing or not the size of views {k} and {j}",
                    view.target
                ),
            )
        };
        let real = real.ok_or_else(size_error)?;
        let set = synthesised.pixels().filter(|p| p.0[0] > 0).count();
        Ok(ViewScore {
            scene: scene.name.clone(),
            pair: view.pair,
            target: view.target,
            psnr_all: psnr(&view.image, real, None).ok_or_else(size_error)?,
            ssim_all: ssim(&view.image, real, None).ok_or_else(size_error)?,
            psnr_synthesised: psnr(&view.image, real, Some(synthesised)),
            synthesised: set as f64 / (synthesised.width() * synthesised.height()).max(1) as f64,
        })
    }
}

/// Extrapolates `scene` at a baseline of `step` views (see
/// [`extrapolate_scene`]) and scores every new view, the synthesised
/// pixels by its own mask.
pub fn evaluate_scene(
    scene: &Scene,
    extrapolator: &Extrapolator,
    source: &DisparitySource,
    step: usize,
) -> Result<Vec<ViewScore>, ExtrapolateError> {
    extrapolate_scene(scene, extrapolator, source, step)?
        .iter()
        .map(|view| ViewScore::of(scene, view, &view.mask))
        .collect()
}

/// The union of two masks of one size (255 where either is set).
pub fn mask_union(a: &MaskImage, b: &MaskImage) -> MaskImage {
    let mut union = a.clone();
    for (u, v) in union.iter_mut().zip(b.iter()) {
        *u = (*u).max(*v);
    }
    union
}

/// Mean scores of a set of views.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanScore {
    /// Views averaged.
    pub views: usize,
    /// Mean PSNR (dB) over all pixels.
    pub psnr_all: f64,
    /// Mean SSIM over all pixels.
    pub ssim_all: f64,
    /// Mean PSNR (dB) over synthesised pixels, of the views that have some.
    pub psnr_synthesised: f64,
    /// Mean share of synthesised pixels.
    pub synthesised: f64,
}

/// The mean of `scores` (`None` when empty).
pub fn mean_score<'a>(scores: impl IntoIterator<Item = &'a ViewScore>) -> Option<MeanScore> {
    let scores: Vec<&ViewScore> = scores.into_iter().collect();
    if scores.is_empty() {
        return None;
    }
    let n = scores.len() as f64;
    let synthesised: Vec<f64> = scores.iter().filter_map(|s| s.psnr_synthesised).collect();
    Some(MeanScore {
        views: scores.len(),
        psnr_all: scores.iter().map(|s| s.psnr_all).sum::<f64>() / n,
        ssim_all: scores.iter().map(|s| s.ssim_all).sum::<f64>() / n,
        psnr_synthesised: synthesised.iter().sum::<f64>() / synthesised.len().max(1) as f64,
        synthesised: scores.iter().map(|s| s.synthesised).sum::<f64>() / n,
    })
}

/// A Markdown table of the mean per scene and over all views.
pub fn score_table(scores: &[ViewScore]) -> String {
    let mut names: Vec<&str> = scores.iter().map(|s| s.scene.as_str()).collect();
    names.dedup();
    let mut table = String::from(
        "| scene | views | PSNR all (dB) | SSIM all | PSNR synthesised (dB) | synthesised |\n| --- | ---: | ---: | ---: | ---: | ---: |\n",
    );
    let rows = names
        .iter()
        .map(|name| {
            (
                name.to_string(),
                mean_score(scores.iter().filter(|s| s.scene == *name)),
            )
        })
        .chain(std::iter::once(("mean".to_string(), mean_score(scores))));
    for (name, mean) in rows {
        if let Some(m) = mean {
            table.push_str(&format!(
                "| {name} | {} | {:.2} | {:.3} | {:.2} | {:.1} % |\n",
                m.views,
                m.psnr_all,
                m.ssim_all,
                m.psnr_synthesised,
                100.0 * m.synthesised
            ));
        }
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_disparity_offset_turns_negative_disparities_positive() {
        // View k shows the texture at x + k * d with d = -2: disparity -2.
        let texture = |x: i64| ((x * 37 + 11) % 251) as u8;
        let views: Vec<RgbImage> = (0..4i64)
            .map(|k| {
                RgbImage::from_fn(20, 3, |x, _| {
                    image::Rgb([texture(x as i64 + 10 - 2 * k); 3])
                })
            })
            .collect();
        let scene = Scene {
            name: "converged".into(),
            views,
        };
        let shifted = scene.with_disparity_offset(3).unwrap();
        assert!(shifted.views.iter().all(|v| v.dimensions() == (11, 3)));
        // Now a pixel at u in view k is at u - 1 in view k + 1.
        for pair in shifted.views.windows(2) {
            for u in 1..11 {
                assert_eq!(pair[0].get_pixel(u, 1), pair[1].get_pixel(u - 1, 1));
            }
        }
        let Err(err) = shifted.with_disparity_offset(4) else {
            panic!("an offset wider than the views was accepted");
        };
        let err = err.to_string();
        assert!(
            err.contains("converged: a disparity offset of 4 px leaves no column"),
            "{err}"
        );
    }
}
