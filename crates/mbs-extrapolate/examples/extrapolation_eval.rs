//! The extrapolation evaluation on the real scenes of `testdata/`: every
//! pair of views one and two steps apart extrapolated with the built-in
//! matcher, the new views scored against the real views one baseline
//! further out, for the default settings and the alternatives, as Markdown
//! tables (README, BENCHMARKS). With `--json`, one line of per-scene means
//! of the default settings for `tools/bench/extrapolation_vs_opencv.py`.
//! With `--hci DIR`, the HCI light-field scene "antinous" (its centre row,
//! `input_Cam036.png` .. `input_Cam044.png`; CC BY-NC-SA, so not shipped:
//! `../shared/data/hci-antinous-row4` in the team's checkout) joins the
//! scenes, its disparities (-3.1 .. 2.7 px per view) offset by 4 px.
//!
//! `cargo run --release -p mbs-extrapolate --example extrapolation_eval [-- --json] [-- --hci DIR]`

use std::path::Path;

use mbs_core::RgbImage;
use mbs_extrapolate::disparity::MAX_ESTIMATED_DISPARITY;
use mbs_extrapolate::evaluation::{
    Scene, ViewScore, evaluate_scene, extrapolate_scene, mask_union, mean_score, score_table,
};
use mbs_extrapolate::{DisparitySource, ExtrapolateError, Extrapolator};
use mbs_infer::inpaint::{BackgroundFill, Inpainter, IsotropicFill};
use mbs_infer::{Disparity, InferError, Sgm, SgmConfig, StereoMatcher, estimate_max_disparity};
use mbs_warp::Dilation;

/// Disparity offset (px per view step) that makes the HCI scene's
/// disparities (-3.13 .. 2.69 px) positive.
const HCI_OFFSET: u32 = 4;

/// Makes a fresh inpainter for one setting.
type NewInpainter = fn() -> Box<dyn Inpainter>;

/// The built-in matcher with its matching defaults and no median filter:
/// the disparity source of `extrapolate` before it was tuned for warping.
struct MatchingDefaults;

impl MatchingDefaults {
    fn sgm(left: &RgbImage, right: &RgbImage) -> Result<Sgm, InferError> {
        let max = estimate_max_disparity(left, right, MAX_ESTIMATED_DISPARITY)?;
        Ok(Sgm::new(SgmConfig::with_max_disparity(max)))
    }
}

impl StereoMatcher for MatchingDefaults {
    fn name(&self) -> &str {
        "sgm-matching-defaults"
    }

    fn predict(&self, left: &RgbImage, right: &RgbImage) -> Result<Disparity, InferError> {
        Self::sgm(left, right)?.predict(left, right)
    }

    fn predict_right(&self, left: &RgbImage, right: &RgbImage) -> Result<Disparity, InferError> {
        Self::sgm(left, right)?.predict_right(left, right)
    }
}

/// One setting: its name, whether it uses the matching defaults, the
/// dilation and the inpainter.
type Setting = (&'static str, bool, Dilation, NewInpainter);

const SETTINGS: [Setting; 6] = [
    (
        "SGM for warping, no dilation, background fill (default)",
        false,
        Dilation::None,
        || Box::new(BackgroundFill::default()),
    ),
    (
        "SGM matching defaults, no median (before)",
        true,
        Dilation::None,
        || Box::new(BackgroundFill::default()),
    ),
    (
        "background-side dilation 2",
        false,
        Dilation::BackgroundSide(2),
        || Box::new(BackgroundFill::default()),
    ),
    (
        "square dilation 2 (the paper's kind)",
        false,
        Dilation::Square(2),
        || Box::new(BackgroundFill::default()),
    ),
    (
        "foreground-side dilation 2",
        false,
        Dilation::ForegroundSide(2),
        || Box::new(BackgroundFill::default()),
    ),
    ("isotropic fill", false, Dilation::None, || {
        Box::new(IsotropicFill)
    }),
];

fn source(matching_defaults: bool) -> DisparitySource {
    if matching_defaults {
        DisparitySource::Matcher(Box::new(MatchingDefaults))
    } else {
        DisparitySource::Sgm { max_disparity: 0 }
    }
}

fn evaluate(
    scenes: &[Scene],
    setting: &Setting,
    step: usize,
) -> Result<Vec<ViewScore>, ExtrapolateError> {
    let (_, matching_defaults, dilation, inpainter) = setting;
    let extrapolator = Extrapolator::new(*dilation, inpainter());
    let source = source(*matching_defaults);
    let mut scores = Vec::new();
    for scene in scenes {
        scores.extend(evaluate_scene(scene, &extrapolator, &source, step)?);
    }
    Ok(scores)
}

/// Synthesised-pixel PSNR of the default and the `before` setting over the
/// same pixels: the union of both masks, view by view.
fn shared_mask_psnr(scenes: &[Scene], step: usize) -> Result<(f64, f64), ExtrapolateError> {
    let extrapolator = Extrapolator::new(Dilation::None, Box::new(BackgroundFill::default()));
    let (mut now, mut before) = (Vec::new(), Vec::new());
    for scene in scenes {
        let new = extrapolate_scene(scene, &extrapolator, &source(false), step)?;
        let old = extrapolate_scene(scene, &extrapolator, &source(true), step)?;
        for (n, o) in new.iter().zip(&old) {
            let union = mask_union(&n.mask, &o.mask);
            now.push(ViewScore::of(scene, n, &union)?);
            before.push(ViewScore::of(scene, o, &union)?);
        }
    }
    let synthesised =
        |scores: &[ViewScore]| mean_score(scores).map_or(f64::NAN, |m| m.psnr_synthesised);
    Ok((synthesised(&now), synthesised(&before)))
}

fn json_line(scenes: &[Scene]) -> Result<String, ExtrapolateError> {
    let mut steps = serde_json::Map::new();
    for step in [1, 2] {
        let scores = evaluate(scenes, &SETTINGS[0], step)?;
        let mut per_scene = serde_json::Map::new();
        for scene in scenes {
            if let Some(m) = mean_score(scores.iter().filter(|s| s.scene == scene.name)) {
                per_scene.insert(
                    scene.name.clone(),
                    serde_json::json!({
                        "views": m.views, "psnr_all": m.psnr_all, "ssim_all": m.ssim_all,
                        "psnr_synthesised": m.psnr_synthesised, "synthesised": m.synthesised,
                    }),
                );
            }
        }
        steps.insert(format!("step{step}"), per_scene.into());
    }
    Ok(serde_json::Value::from(steps).to_string())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let testdata = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata");
    let mut scenes = Scene::shipped(&testdata)?;
    let args: Vec<String> = std::env::args().collect();
    if let Some(dir) = args
        .iter()
        .position(|a| a == "--hci")
        .and_then(|i| args.get(i + 1))
    {
        let views: Vec<_> = (36..=44)
            .map(|k| Path::new(dir).join(format!("input_Cam{k:03}.png")))
            .collect();
        scenes.push(Scene::load("HCI antinous", &views)?.with_disparity_offset(HCI_OFFSET)?);
    }
    if std::env::args().any(|a| a == "--json") {
        println!("{}", json_line(&scenes)?);
        return Ok(());
    }
    let mut summary = String::from(
        "| settings | PSNR all (dB) | SSIM all | PSNR synthesised (dB) | at 2x baseline: PSNR all | SSIM all | PSNR synthesised |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for (i, setting) in SETTINGS.iter().enumerate() {
        summary.push_str(&format!("| {} ", setting.0));
        for step in [1, 2] {
            let scores = evaluate(&scenes, setting, step)?;
            if i == 0 {
                println!(
                    "{} views apart, {}:\n\n{}",
                    step,
                    setting.0,
                    score_table(&scores)
                );
            }
            if let Some(m) = mean_score(&scores) {
                summary.push_str(&format!(
                    "| {:.2} | {:.3} | {:.2} ",
                    m.psnr_all, m.ssim_all, m.psnr_synthesised
                ));
            }
        }
        summary.push_str("|\n");
    }
    println!("Mean over every view of every scene:\n\n{summary}");
    for step in [1, 2] {
        let (now, before) = shared_mask_psnr(&scenes, step)?;
        println!(
            "{step} views apart, synthesised pixels of either mask: default {now:.2} dB, before {before:.2} dB"
        );
    }
    Ok(())
}
