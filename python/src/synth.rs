//! `mbs._native.synth_scene`: one procedural street scene rendered from a
//! rig, as `mbs-tool synth` renders its frames, with exact ground truth.

use image::RgbImage;
use mbs_core::{FloatImage, Rig};
use mbs_synth::{RenderOptions, Scene, SceneConfig, Weather, one_step_disparity, render};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::integer::Integer;
use crate::{to_numpy, value_error};

/// The most cameras a rig may have here.
const MAX_VIEWS: usize = 16;

/// The most pixels a view may have a side.
const MAX_VIEW_SIDE: usize = 4096;

/// The most pixels of all views together (the views, depth and disparity
/// maps of a call then take at most about 1.3 GB).
const MAX_TOTAL_PIXELS: usize = 1 << 26;

/// Renders a procedural street scene with exact ground truth.
///
/// A scene generated from ``seed``, rendered by exact ray casting from a rig
/// of ``views`` cameras ``baseline`` metres apart (camera ``k`` at ``x = k *
/// baseline``) with the principal point at the centre, as ``mbs-tool synth``
/// renders its frames.
///
/// Parameters
/// ----------
/// seed : int, default 0
///     The scene's seed, 0 to ``2**64 - 1``: a seed gives the same scene
///     every time.
/// views : int, default 5
///     The number of cameras, 2 to 16.
/// width : int, default 192
///     Each view's width in pixels, 8 to 4096.
/// height : int, default 96
///     Each view's height in pixels, 8 to 4096; all views together have at
///     most ``2**26`` pixels.
/// focal : float, default 96.0
///     The focal length in pixels, positive.
/// baseline : float, default 0.5
///     The distance between neighbouring cameras in metres, positive.
/// weather : str, default "ClearNoon"
///     ``"ClearNoon"``, ``"ClearNight"``, ``"ClearSunset"``, ``"CloudyNoon"``
///     or ``"MidRainyNoon"``.
/// supersample : int, default 2
///     ``supersample**2`` samples per pixel, 1 to 4.
///
/// Returns
/// -------
/// dict
///     Lists with one entry per camera: ``views`` (``uint8``, ``(H, W,
///     3)``), ``depth`` (``float32``, ``(H, W)``, planar metres; the sky is
///     1000 m) and ``disparity`` (``float32``, ``(H, W)``, ``focal *
///     baseline / depth``: the exact disparity of a one-baseline pair; ``k``
///     times it for cameras ``k`` apart).
///
/// Raises
/// ------
/// ValueError
///     A setting is out of range or unknown (the message begins with its
///     name).
/// TypeError
///     An integer argument is not an integer (a float, a bool, a string; the
///     message begins with its name).
#[pyfunction]
#[pyo3(
    signature = (seed = Integer::of(0), views = Integer::of(5), width = Integer::of(192), height = Integer::of(96), focal = 96.0, baseline = 0.5, weather = "ClearNoon", supersample = Integer::of(2)),
    text_signature = "(seed=0, views=5, width=192, height=96, focal=96.0, baseline=0.5, weather='ClearNoon', supersample=2)"
)]
#[allow(clippy::too_many_arguments)]
pub fn synth_scene<'py>(
    py: Python<'py>,
    seed: Integer,
    views: Integer,
    width: Integer,
    height: Integer,
    focal: f64,
    baseline: f64,
    weather: &str,
    supersample: Integer,
) -> PyResult<Bound<'py, PyDict>> {
    let seed: u64 = seed.within("seed", 0..=i128::from(u64::MAX))?;
    let views: usize = views.within("views", 2..=MAX_VIEWS as i128)?;
    let width: usize = width.within("width", 8..=MAX_VIEW_SIDE as i128)?;
    let height: usize = height.within("height", 8..=MAX_VIEW_SIDE as i128)?;
    let supersample: u32 = supersample.within("supersample", 1..=4)?;
    check_size_and_optics(views, (width, height), focal, baseline)?;
    let weather = parse_weather(weather)?;
    let rig = Rig::centred(views, baseline, focal, width as u32, height as u32);
    let options = RenderOptions {
        supersample,
        weather,
        ..RenderOptions::default()
    };
    let rendered = py.detach(|| {
        let scene = Scene::generate(seed, &SceneConfig::centred_on(&rig));
        render(&scene, &rig, &options)
    });
    let disparity: Vec<FloatImage> = rendered
        .depth
        .iter()
        .map(|depth| one_step_disparity(depth, &rig))
        .collect();
    let arrays = |images: Vec<RgbImage>| -> PyResult<Vec<_>> {
        images
            .into_iter()
            .map(|image| to_numpy(py, image))
            .collect()
    };
    let maps = |maps: Vec<FloatImage>| -> PyResult<Vec<_>> {
        maps.into_iter().map(|map| to_numpy(py, map)).collect()
    };
    let out = PyDict::new(py);
    out.set_item("views", arrays(rendered.views)?)?;
    out.set_item("depth", maps(rendered.depth)?)?;
    out.set_item("disparity", maps(disparity)?)?;
    Ok(out)
}

/// Refuses more pixels than one call renders, and a focal length or
/// baseline that is not a positive number.
fn check_size_and_optics(
    views: usize,
    (width, height): (usize, usize),
    focal: f64,
    baseline: f64,
) -> PyResult<()> {
    if views * width * height > MAX_TOTAL_PIXELS {
        return Err(value_error(
            "views",
            format!(
                "{views} views of {width}x{height} are {} pixels, more than the {MAX_TOTAL_PIXELS} \
                 one call renders; render fewer or smaller views",
                views * width * height
            ),
        ));
    }
    for (name, value) in [("focal", focal), ("baseline", baseline)] {
        if !(value.is_finite() && value > 0.0) {
            return Err(value_error(
                name,
                format!("{value}: expected a positive number"),
            ));
        }
    }
    Ok(())
}

/// The `weather` argument: one of MBS20K's weather names.
fn parse_weather(weather: &str) -> PyResult<Weather> {
    serde_json::from_value(serde_json::Value::from(weather)).map_err(|_| {
        value_error(
            "weather",
            format!(
                "{weather:?} is not ClearNoon, ClearNight, ClearSunset, CloudyNoon or MidRainyNoon"
            ),
        )
    })
}
