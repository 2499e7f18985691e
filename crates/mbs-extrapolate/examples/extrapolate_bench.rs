//! Benchmark of novel-view extrapolation (both warps, masks, dilation and
//! inpainting; disparity estimation excluded) on a KITTI-size frame, plus the
//! quality of the same pipeline on Tsukuba. Driven by
//! `tools/bench/extrapolate_vs_numpy.py`, which runs the numpy/OpenCV peer on
//! the inputs this example writes.
//!
//! `cargo run --release -p mbs-extrapolate --example extrapolate_bench -- OUT_DIR [FRAMES [RADIUS]]`
//! (RADIUS: dilate the holes by a disc of that radius; default none, the
//! measured best on Tsukuba) writes into OUT_DIR the KITTI-size frame
//! (`left.png`, `right.png`, `disp_left.pfm`, `disp_right.pfm`) and
//! Tsukuba's derived disparities (`tsukuba_disp3.pfm`, `tsukuba_disp4.pfm`),
//! then prints one JSON line.

#[path = "../tests/common/mod.rs"]
mod common;

use std::path::PathBuf;
use std::time::Instant;

use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_core::formats::rgb::write_rgb_png;
use mbs_core::{FloatImage, RgbImage};
use mbs_extrapolate::{Disparities, Extrapolator};
use mbs_infer::inpaint::BackgroundFill;
use mbs_warp::Dilation;

/// KITTI 2015 frame size.
const WIDTH: u32 = 1242;
const HEIGHT: u32 = 375;
/// Tsukuba disparities reach 14 px; KITTI's reach about 3x that in the
/// lower image half.
const DISPARITY_SCALE: f32 = 3.0;

fn tile_rgb(src: &RgbImage) -> RgbImage {
    RgbImage::from_fn(WIDTH, HEIGHT, |x, y| {
        *src.get_pixel(x % src.width(), y % src.height())
    })
}

fn tile_disp(src: &FloatImage) -> FloatImage {
    FloatImage::from_fn(WIDTH, HEIGHT, |x, y| {
        image::Luma([src.get_pixel(x % src.width(), y % src.height()).0[0] * DISPARITY_SCALE])
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(
        args.next()
            .ok_or("usage: extrapolate_bench OUT_DIR [FRAMES [RADIUS]]")?,
    );
    let frames: usize = args.next().map_or(Ok(30), |f| f.parse())?;
    let dilation = match args.next() {
        Some(r) => Dilation::Ellipse(r.parse()?),
        None => Dilation::default(),
    };
    let extrapolator = Extrapolator::new(dilation, Box::new(BackgroundFill::default()));

    let t = common::load();
    let (left, right) = (tile_rgb(&t.views[2]), tile_rgb(&t.views[3]));
    let (disp_left, disp_right) = (tile_disp(&t.disp3), tile_disp(&t.disp4));
    write_rgb_png(&out.join("left.png"), &left)?;
    write_rgb_png(&out.join("right.png"), &right)?;
    write_pfm_grey(&out.join("disp_left.pfm"), &disp_left, Endian::Little)?;
    write_pfm_grey(&out.join("disp_right.pfm"), &disp_right, Endian::Little)?;
    write_pfm_grey(&out.join("tsukuba_disp3.pfm"), &t.disp3, Endian::Little)?;
    write_pfm_grey(&out.join("tsukuba_disp4.pfm"), &t.disp4, Endian::Little)?;

    let disparities = Disparities {
        left: disp_left,
        right: disp_right,
    };
    let frame = || extrapolator.extrapolate(&left, &right, &disparities);
    frame()?; // warm-up
    let mut times = Vec::with_capacity(frames);
    for _ in 0..frames {
        let start = Instant::now();
        std::hint::black_box(frame()?);
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let mean = times.iter().sum::<f64>() / times.len() as f64;

    let s = common::score(&t, &common::extrapolate(&t, &extrapolator));
    println!(
        "{{\"frames\": {frames}, \"threads\": {}, \"dilation\": \"{dilation:?}\", \"ms_median\": {median:.3}, \"ms_mean\": {mean:.3}, \
         \"tsukuba_psnr_all\": {:.3}, \"tsukuba_psnr_holes\": {:.3}, \"tsukuba_ssim_all\": {:.4}, \"tsukuba_ssim_holes\": {:.4}}}",
        rayon::current_num_threads(),
        s.psnr_all,
        s.psnr_holes,
        s.ssim_all,
        s.ssim_holes
    );
    Ok(())
}
