//! Novel-view extrapolation on real data (Middlebury Tsukuba, five equally
//! spaced views): from (col3, col4) synthesise col2 and col5 and compare them
//! with the real views. Numbers are printed; run with `--nocapture`.

mod common;

use mbs_infer::inpaint::{BackgroundFill, Inpainter, IsotropicFill};
use mbs_warp::Dilation;

#[test]
fn measure_inpainters_and_dilations_on_tsukuba() {
    let t = common::load();
    let inpainters: Vec<(&str, Box<dyn Inpainter>)> = vec![
        ("background (default)", Box::new(BackgroundFill::default())),
        (
            "background, repeat border",
            Box::new(BackgroundFill {
                mirror: false,
                ..BackgroundFill::default()
            }),
        ),
        (
            "background, no smoothing",
            Box::new(BackgroundFill {
                smoothing_passes: 0,
                ..BackgroundFill::default()
            }),
        ),
        (
            "background, 6 smoothing",
            Box::new(BackgroundFill {
                smoothing_passes: 6,
                ..BackgroundFill::default()
            }),
        ),
        ("isotropic", Box::new(IsotropicFill)),
    ];
    let dilations = [
        Dilation::None,
        Dilation::Square(1),
        Dilation::Square(2),
        Dilation::Ellipse(2),
        Dilation::Ellipse(4),
        Dilation::BackgroundSide(1),
        Dilation::BackgroundSide(2),
        Dilation::BackgroundSide(4),
    ];
    println!(
        "{:<28} {:<18} {:>8} {:>8} {:>7} {:>7}",
        "inpainter", "dilation", "PSNR", "holes", "SSIM", "holes"
    );
    for (name, inpainter) in &inpainters {
        for dilation in dilations {
            let s = common::score(&t, &common::extrapolate(&t, dilation, inpainter.as_ref()));
            println!(
                "{name:<28} {:<18} {:>8.3} {:>8.3} {:>7.4} {:>7.4}",
                format!("{dilation:?}"),
                s.psnr_all,
                s.psnr_holes,
                s.ssim_all,
                s.ssim_holes
            );
        }
    }
}
