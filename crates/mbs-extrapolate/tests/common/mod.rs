//! The Tsukuba extrapolation task shared by the quality tests and the
//! benchmark example: from the pair (col3, col4) synthesise col2 (one step
//! left of col3) and col5 (one step right of col4), and score them against
//! the real views.

use std::path::{Path, PathBuf};

use mbs_core::formats::rgb::read_rgb;
use mbs_core::{FloatImage, MaskImage, RgbImage, Side};
use mbs_extrapolate::disparity::derive_other_view;
use mbs_extrapolate::{Disparities, Extrapolator};
use mbs_image::quality::{psnr, ssim};
use mbs_warp::fill_disparity_background;

/// The Middlebury Tsukuba row-3 folder of the shared data.
pub fn tsukuba_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/middlebury-tsukuba-row3")
}

/// Views col2..col5 and the one-step disparities of col3 and col4.
pub struct Tsukuba {
    /// Real views, `views[k]` = column `k + 1`.
    pub views: Vec<RgbImage>,
    /// Disparity of col3 for one column step: ground truth, unknown border
    /// filled from the background side.
    pub disp3: FloatImage,
    /// Disparity of col4: col3's forward-warped to col4 (z-buffer), holes
    /// filled from the background side.
    pub disp4: FloatImage,
}

/// Loads the views and derives both disparities (see [`Tsukuba`]).
pub fn load() -> Tsukuba {
    let dir = tsukuba_dir();
    let views: Vec<RgbImage> = (1..=5)
        .map(|k| read_rgb(&dir.join(format!("scene1.row3.col{k}.ppm"))).expect("Tsukuba view"))
        .collect();
    let gt = image::open(dir.join("truedisp.row3.col3.pgm"))
        .expect("Tsukuba ground truth")
        .into_luma8();
    let raw = FloatImage::from_fn(gt.width(), gt.height(), |x, y| {
        let v = gt.get_pixel(x, y).0[0];
        image::Luma([if v == 0 {
            f32::INFINITY
        } else {
            f32::from(v) / 16.0
        }])
    });
    let disp3 = fill_disparity_background(&raw);
    let disp4 = derive_other_view(&views[2], &disp3, Side::Right).expect("same size");
    Tsukuba {
        views,
        disp3,
        disp4,
    }
}

/// One synthesised view with what was synthesised.
pub struct Synth {
    /// The extrapolated, inpainted view.
    pub image: RgbImage,
    /// Pixels nothing landed on.
    pub holes: MaskImage,
}

/// Synthesises col2 from col3 and col5 from col4.
pub fn extrapolate(t: &Tsukuba, extrapolator: &Extrapolator) -> [Synth; 2] {
    let disparities = Disparities {
        left: t.disp3.clone(),
        right: t.disp4.clone(),
    };
    let views = extrapolator
        .extrapolate(&t.views[2], &t.views[3], &disparities)
        .expect("same size");
    [
        Synth {
            image: views.image_1,
            holes: views.holes_1,
        },
        Synth {
            image: views.image_4,
            holes: views.holes_4,
        },
    ]
}

/// Scores of the two synthesised views against the real col2 and col5.
#[derive(Debug, Clone, Copy)]
pub struct Scores {
    /// PSNR (dB) over all pixels, mean of the two views.
    pub psnr_all: f64,
    /// PSNR (dB) over the hole pixels, mean of the two views.
    pub psnr_holes: f64,
    /// SSIM over all pixels, mean of the two views.
    pub ssim_all: f64,
    /// SSIM over the hole pixels, mean of the two views.
    pub ssim_holes: f64,
}

/// Scores `synth` (col2, col5) against the real views.
pub fn score(t: &Tsukuba, synth: &[Synth; 2]) -> Scores {
    let real = [&t.views[1], &t.views[4]];
    let mean = |f: &dyn Fn(&Synth, &RgbImage) -> f64| {
        (f(&synth[0], real[0]) + f(&synth[1], real[1])) / 2.0
    };
    Scores {
        psnr_all: mean(&|s, r| psnr(&s.image, r, None).expect("same size")),
        psnr_holes: mean(&|s, r| psnr(&s.image, r, Some(&s.holes)).expect("holes exist")),
        ssim_all: mean(&|s, r| ssim(&s.image, r, None).expect("same size")),
        ssim_holes: mean(&|s, r| ssim(&s.image, r, Some(&s.holes)).expect("holes exist")),
    }
}
