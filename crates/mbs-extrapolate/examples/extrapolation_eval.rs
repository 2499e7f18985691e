//! The extrapolation evaluation on the real scenes of `testdata/`: every
//! adjacent pair extrapolated with the built-in matcher, the new views
//! scored against the real views one step further out, for the default
//! settings and the alternatives, as Markdown tables (README, BENCHMARKS).
//!
//! `cargo run --release -p mbs-extrapolate --example extrapolation_eval`

use std::path::Path;

use mbs_extrapolate::evaluation::{Scene, evaluate_scene, mean_score, score_table};
use mbs_extrapolate::{DisparitySource, Extrapolator};
use mbs_infer::inpaint::{BackgroundFill, Inpainter, IsotropicFill};
use mbs_warp::Dilation;

/// Makes a fresh inpainter for one setting.
type NewInpainter = fn() -> Box<dyn Inpainter>;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let testdata = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata");
    let scenes = Scene::shipped(&testdata)?;
    let source = DisparitySource::Sgm { max_disparity: 0 };
    let settings: [(&str, Dilation, NewInpainter); 5] = [
        (
            "no dilation, background fill (default)",
            Dilation::None,
            || Box::new(BackgroundFill::default()),
        ),
        (
            "background-side dilation 2, background fill",
            Dilation::BackgroundSide(2),
            || Box::new(BackgroundFill::default()),
        ),
        (
            "square dilation 2, background fill",
            Dilation::Square(2),
            || Box::new(BackgroundFill::default()),
        ),
        (
            "foreground-side dilation 2, background fill",
            Dilation::ForegroundSide(2),
            || Box::new(BackgroundFill::default()),
        ),
        ("no dilation, isotropic fill", Dilation::None, || {
            Box::new(IsotropicFill)
        }),
    ];
    let mut summary = String::from(
        "| settings | PSNR all (dB) | SSIM all | PSNR synthesised (dB) |\n| --- | ---: | ---: | ---: |\n",
    );
    for (i, (name, dilation, inpainter)) in settings.into_iter().enumerate() {
        let extrapolator = Extrapolator::new(dilation, inpainter());
        let mut scores = Vec::new();
        for scene in &scenes {
            scores.extend(evaluate_scene(scene, &extrapolator, &source)?);
        }
        if i == 0 {
            println!("{name}:\n\n{}", score_table(&scores));
        }
        if let Some(m) = mean_score(&scores) {
            summary.push_str(&format!(
                "| {name} | {:.2} | {:.3} | {:.2} |\n",
                m.psnr_all, m.ssim_all, m.psnr_synthesised
            ));
        }
    }
    println!("Mean over every view of every scene:\n\n{summary}");
    Ok(())
}
