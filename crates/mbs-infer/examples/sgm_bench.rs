//! Times the built-in SGM on one pair and scores it against ground truth;
//! called by `tools/bench/sgm_vs_opencv.py`. Run in release:
//!
//! ```text
//! cargo run --release -p mbs-infer --example sgm_bench -- \
//!     LEFT RIGHT MAX_DISP REPEATS [PATHS(5|8)] [GT GT_SCALE]
//! ```
//!
//! GT is an 8-bit (Middlebury, `value / GT_SCALE`, 0 = unknown) or 16-bit
//! (KITTI, `value / 256`) PNG. Prints one JSON object: the median time per
//! pair in milliseconds (and the fastest) and EPE / Out-1 / Out-2 / Out-3 over all valid GT.

use std::path::Path;
use std::time::Instant;

use mbs_core::FloatImage;
use mbs_core::formats::rgb::read_rgb;
use mbs_eval::{Dataset, Frame, Metrics, Protocol, Region, rules_for};
use mbs_infer::{Sgm, SgmConfig, SgmPaths, StereoMatcher};

type BoxError = Box<dyn std::error::Error>;

fn read_gt(path: &Path, scale: f32) -> Result<FloatImage, BoxError> {
    let image = image::open(path)?;
    let decode = |v: u16, s: f32| {
        if v == 0 {
            f32::INFINITY
        } else {
            f32::from(v) / s
        }
    };
    let values: Vec<f32> = match &image {
        image::DynamicImage::ImageLuma16(g) => {
            g.as_raw().iter().map(|&v| decode(v, 256.0)).collect()
        }
        other => other
            .to_luma8()
            .as_raw()
            .iter()
            .map(|&v| decode(v.into(), scale))
            .collect(),
    };
    FloatImage::from_raw(image.width(), image.height(), values)
        .ok_or_else(|| "ground truth size mismatch".into())
}

/// The `pixels` protocol's figures over all valid ground truth, at Out-1,
/// 2 and 3.
fn pixels(prediction: &FloatImage, truth: &FloatImage) -> Result<Metrics, BoxError> {
    let rules = rules_for(Protocol::Pixels, Dataset::Other, &[1.0, 2.0, 3.0])?;
    let frame = Frame {
        prediction,
        gt: truth,
        noc: None,
        disparity_bound: None,
    };
    let score = rules.score(&frame)?;
    let all = score.get(Region::All).ok_or("no ALL region")?;
    Ok(rules.metrics(all))
}

fn main() -> Result<(), BoxError> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 4 {
        return Err("usage: sgm_bench LEFT RIGHT MAX_DISP REPEATS [PATHS] [GT GT_SCALE]".into());
    }
    let (left, right) = (
        read_rgb(Path::new(&args[0]))?,
        read_rgb(Path::new(&args[1]))?,
    );
    let mut config = SgmConfig::with_max_disparity(args[2].parse()?);
    let repeats: usize = args[3].parse()?;
    if args.get(4).map(String::as_str) == Some("8") {
        config.paths = SgmPaths::Eight;
    }
    let sgm = Sgm::new(config);
    let mut prediction = sgm.predict(&left, &right)?; // warm-up
    let mut times = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let start = Instant::now();
        prediction = sgm.predict(&left, &right)?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let median = times.get(times.len() / 2).copied().unwrap_or(f64::NAN);
    let min = times.first().copied().unwrap_or(f64::NAN);
    let mut json = format!("{{\"time_ms\": {median:.3}, \"min_ms\": {min:.3}");
    if let (Some(gt), Some(scale)) = (args.get(5), args.get(6)) {
        let truth = read_gt(Path::new(gt), scale.parse()?)?;
        let m = pixels(&prediction.disparity, &truth)?;
        let num = |v: Option<f64>| v.map_or("null".to_string(), |v| format!("{v:.4}"));
        json += &format!(
            ", \"epe\": {}, \"out1\": {}, \"out2\": {}, \"out3\": {}",
            num(m.epe),
            num(m.out(1.0)),
            num(m.out(2.0)),
            num(m.out(3.0))
        );
    }
    println!("{json}}}");
    Ok(())
}
