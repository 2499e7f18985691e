//! The extrapolation evaluation on the real scenes of `testdata/`: every
//! pair of views one and two steps apart extrapolated with the built-in
//! matcher, the new views scored against the real views one baseline
//! further out, for the default settings and the alternatives, as Markdown
//! tables (docs/quality.md, BENCHMARKS.md). With `--json`, one line of per-scene means
//! of the default settings for `tools/bench/extrapolation_vs_opencv.py`.
//! With `--hci DIR`, the HCI light-field scene "antinous" (its centre row,
//! `input_Cam036.png` .. `input_Cam044.png`; CC BY-NC-SA, so not shipped:
//! `../shared/data/hci-antinous-row4` in the team's checkout) joins the
//! scenes, its disparities (-3.1 .. 2.7 px per view) offset by 4 px.
//!
//! `cargo run --release -p mbs-extrapolate --example extrapolation_eval [-- --json] [-- --hci DIR]`

use std::path::Path;

use mbs_extrapolate::evaluation::{
    ExtrapolatedView, Scene, ViewScore, extrapolate_scene, mask_union, mean_score, score_table,
};
use mbs_extrapolate::{DisparitySource, ExtrapolateError, Extrapolator};
use mbs_infer::inpaint::{BackgroundFill, Inpainter, IsotropicFill};
use mbs_infer::{Sgm, SgmConfig};
use mbs_warp::Dilation;

/// Disparity offset (px per view step) that makes the HCI scene's
/// disparities (-3.13 .. 2.69 px) positive.
const HCI_OFFSET: u32 = 4;

/// Makes a fresh inpainter for one setting.
type NewInpainter = fn() -> Box<dyn Inpainter>;

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
        // The built-in matcher with its matching defaults (range estimated
        // per pair) and no median filter: the disparity source of
        // `extrapolate` before it was tuned for warping.
        DisparitySource::Matcher(Box::new(Sgm::new(SgmConfig::with_max_disparity(0))))
    } else {
        DisparitySource::builtin(0)
    }
}

/// The new views of every scene (with the index of their scene) for one
/// setting, pairs `step` views apart.
type Views = Vec<(usize, ExtrapolatedView)>;

fn extrapolate_all(
    scenes: &[Scene],
    setting: &Setting,
    step: usize,
) -> Result<Views, ExtrapolateError> {
    let (_, matching_defaults, dilation, inpainter) = setting;
    let extrapolator = Extrapolator::new(*dilation, inpainter());
    let source = source(*matching_defaults);
    let mut views = Vec::new();
    for (i, scene) in scenes.iter().enumerate() {
        let new = extrapolate_scene(scene, &extrapolator, &source, step)?;
        views.extend(new.into_iter().map(|view| (i, view)));
    }
    Ok(views)
}

/// The scores of `views`, the synthesised pixels by each view's own mask.
fn score(scenes: &[Scene], views: &Views) -> Result<Vec<ViewScore>, ExtrapolateError> {
    views
        .iter()
        .map(|(i, view)| ViewScore::of(&scenes[*i], view, &view.mask))
        .collect()
}

/// Synthesised-pixel PSNR of the default's and the `before` setting's
/// views over the same pixels: the union of both masks, view by view.
fn shared_mask_psnr(
    scenes: &[Scene],
    default: &Views,
    before: &Views,
) -> Result<(f64, f64), ExtrapolateError> {
    let (mut now, mut then) = (Vec::new(), Vec::new());
    for ((i, new), (_, old)) in default.iter().zip(before) {
        let union = mask_union(&new.mask, &old.mask);
        now.push(ViewScore::of(&scenes[*i], new, &union)?);
        then.push(ViewScore::of(&scenes[*i], old, &union)?);
    }
    let synthesised =
        |scores: &[ViewScore]| mean_score(scores).map_or(f64::NAN, |m| m.psnr_synthesised);
    Ok((synthesised(&now), synthesised(&then)))
}

fn json_line(scenes: &[Scene]) -> Result<String, ExtrapolateError> {
    let mut steps = serde_json::Map::new();
    for step in [1, 2] {
        let scores = score(scenes, &extrapolate_all(scenes, &SETTINGS[0], step)?)?;
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
    if args.iter().any(|a| a == "--json") {
        println!("{}", json_line(&scenes)?);
        return Ok(());
    }
    let mut summary = String::from(
        "| settings | PSNR all (dB) | SSIM all | PSNR synthesised (dB) | at 2x baseline: PSNR all | SSIM all | PSNR synthesised |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    // The views of the default and the `before` setting, per step, for the
    // shared-mask comparison.
    let (mut default_views, mut before_views) = (Vec::new(), Vec::new());
    for (i, setting) in SETTINGS.iter().enumerate() {
        summary.push_str(&format!("| {} ", setting.0));
        for step in [1, 2] {
            let views = extrapolate_all(&scenes, setting, step)?;
            let scores = score(&scenes, &views)?;
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
            match i {
                0 => default_views.push(views),
                1 => before_views.push(views),
                _ => {}
            }
        }
        summary.push_str("|\n");
    }
    println!("Mean over every view of every scene:\n\n{summary}");
    for ((step, default), before) in [1, 2].iter().zip(&default_views).zip(&before_views) {
        let (now, then) = shared_mask_psnr(&scenes, default, before)?;
        println!(
            "{step} views apart, synthesised pixels of either mask: default {now:.2} dB, before {then:.2} dB"
        );
    }
    Ok(())
}
