//! `mbs._native.mono_views`: one image and its depth (or disparity) map, from
//! the caller's own network, into the cameras of a virtual rig, as
//! `mbs_extrapolate::mono` makes them (issue 60): the map scaled to one
//! baseline's disparity, every other camera warped, masked and inpainted by
//! the same `synthesize` as `extrapolate`.

use std::path::Path;

use image::RgbImage;
use mbs_core::FloatImage;
use mbs_core::limits::MAX_VIEWS;
use mbs_extrapolate::disparity::checked_disparity;
use mbs_extrapolate::mono::{MonoViews, Scaling, ViewLayout, virtual_disparity};
use mbs_extrapolate::{Extrapolator, NewView};
use mbs_infer::DepthKind;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::integer::Integer;
use crate::{float_map, parse_dilation, parse_inpainter, rgb_image, to_numpy, value_error};

/// The views of a virtual rig from one image and its depth or disparity.
///
/// For a depth network of your own (a single-image *Learning Stereo from
/// Single Images* set): the map becomes one baseline's disparity of a
/// virtual rig (``scale``), and every camera but the image's is the image
/// forward-warped by ``|k - reference|`` times that disparity, its holes
/// grown by ``dilation`` and inpainted, as :func:`extrapolate` makes its
/// views.
///
/// Parameters
/// ----------
/// image : numpy.ndarray
///     ``uint8``, shape ``(H, W, 3)``, RGB.
/// depth : numpy.ndarray
///     ``float32``, shape ``(H, W)``: the image's map, of kind ``kind``;
///     every value finite, but that a disparity may have ``inf`` where
///     unknown (filled from the background side, as :func:`extrapolate`
///     and ``mbs-tool mono`` fill it).
/// kind : str
///     What ``depth`` holds: ``"metric-depth"`` (metres, positive),
///     ``"inverse-relative"`` (inverse depth up to scale and shift, as
///     MiDaS or relative Depth Anything give) or ``"disparity"`` (pixels,
///     non-negative).
/// views : int, default 4
///     The number of cameras, one baseline apart, 2 to 64.
/// reference : int, default 1
///     The image's camera, 0 to ``views - 1`` (the default is the paper's:
///     one camera left of the image, two right).
/// scale : str, optional
///     How the map becomes one baseline's disparity: ``"as-is"`` (a
///     disparity in pixels, kind ``"disparity"`` only), ``"metric"``
///     (``focal * baseline / depth``, kind ``"metric-depth"`` only) or
///     ``"range"`` (any kind: the map as inverse depth, shifted so that its
///     least value is 0 if negative, scaled so that its largest is a fraction
///     of the width drawn from ``max_disparity``). The default is
///     ``"as-is"`` for a disparity, ``"range"`` otherwise.
/// max_disparity : tuple of float, default (0.05, 0.15)
///     With ``"range"``: ``(low, high)``, the largest disparity is a
///     fraction of the width drawn uniformly from it per image, from
///     ``seed`` and ``sample_id`` only; ``0 < low <= high < 1``.
/// seed : int, default 0
///     The draw's seed, 0 to ``2**64 - 1``.
/// sample_id : str, default ""
///     The image's id in the draw (``mbs-tool`` uses its file stem).
/// focal, baseline : float, optional
///     With ``"metric"`` (and only then): the virtual rig's focal length in
///     pixels and baseline in metres, positive.
/// dilation : str, default "none"
///     How holes grow: ``"none"``, ``"square"``, ``"ellipse"``,
///     ``"background-side"`` or ``"foreground-side"``.
/// dilate_radius : int, default 2
///     By how many pixels, 0 to 32768.
/// inpaint : str, default "background"
///     How holes are filled: ``"background"`` or ``"isotropic"``.
///
/// Returns
/// -------
/// dict
///     ``views``: one ``uint8`` ``(H, W, 3)`` array per camera (``image``
///     itself at ``reference``); ``masks``: per camera, ``None`` at
///     ``reference``, else ``uint8`` ``(H, W)``, 255 where synthesised;
///     ``disparity``: ``float32`` ``(H, W)``, the image's disparity against
///     a camera one baseline away (camera ``k`` is warped by ``|k -
///     reference|`` times it); ``drawn_fraction``: with ``"range"``, the
///     drawn largest disparity as a fraction of the width, else ``None``.
///
/// Raises
/// ------
/// ValueError
///     An array is not as above or the two differ in size, the map has a
///     value its kind cannot hold (NaN; ``inf`` but in a disparity; a depth
///     of zero or below; a negative disparity; one value only, or none
///     known), a setting is unknown, out of range or not allowed with the
///     kind or scale, or every pixel of a view would be synthesised (the
///     message begins with the argument's name).
/// TypeError
///     An integer argument is not an integer (the message begins with its
///     name).
///
/// Example::
///
///     depth = my_network(image)                     # your PyTorch model's float32 HxW
///     rig = mbs.mono_views(image, depth, "inverse-relative", seed=7, sample_id="0001")
///     left, image, right, far_right = rig["views"]  # the paper's four cameras
///     synthesised = rig["masks"][2]                 # 255 where right was inpainted
#[pyfunction]
#[pyo3(
    signature = (image, depth, kind, *, views = Integer::of(4), reference = Integer::of(1), scale = None, max_disparity = vec![0.05, 0.15], seed = Integer::of(0), sample_id = "", focal = None, baseline = None, dilation = "none", dilate_radius = Integer::of(2), inpaint = "background"),
    text_signature = "(image, depth, kind, *, views=4, reference=1, scale=None, max_disparity=(0.05, 0.15), seed=0, sample_id='', focal=None, baseline=None, dilation='none', dilate_radius=2, inpaint='background')"
)]
#[allow(clippy::too_many_arguments)] // the keyword arguments of `mbs.mono_views`
pub fn mono_views<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    depth: &Bound<'py, PyAny>,
    kind: &str,
    views: Integer,
    reference: Integer,
    scale: Option<&str>,
    max_disparity: Vec<f64>,
    seed: Integer,
    sample_id: &str,
    focal: Option<f64>,
    baseline: Option<f64>,
    dilation: &str,
    dilate_radius: Integer,
    inpaint: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let kind: DepthKind = kind.parse().map_err(|e| value_error("kind", e))?;
    let layout = view_layout(views, reference)?;
    let scaling = scaling(kind, scale, &max_disparity, seed, focal, baseline)?;
    let extrapolator = Extrapolator::new(
        parse_dilation(dilation, dilate_radius)?,
        parse_inpainter(inpaint)?,
    );
    let image = rgb_image("image", image)?;
    let map = depth_map(depth, &image, kind)?;
    let (set, disparity) = py.detach(|| {
        let disparity = virtual_disparity(&map, kind, scaling, sample_id)
            .map_err(|e| value_error("scale", e))?;
        let set = extrapolator
            .views_from_one(&image, &disparity.map, layout)
            .map_err(|e| value_error("depth", e))?;
        Ok::<_, PyErr>((set, disparity))
    })?;
    let out = PyDict::new(py);
    let (views, masks) = views_and_masks(py, image, set)?;
    out.set_item("views", views)?;
    out.set_item("masks", masks)?;
    out.set_item("disparity", to_numpy(py, disparity.map)?)?;
    out.set_item("drawn_fraction", disparity.drawn_fraction)?;
    Ok(out)
}

/// The `views` and `reference` arguments as a layout.
fn view_layout(views: Integer, reference: Integer) -> PyResult<ViewLayout> {
    let views: usize = views.within("views", 2..=MAX_VIEWS as i128)?;
    let reference = reference.within("reference", 0..=views as i128 - 1)?;
    ViewLayout::new(views, reference).map_err(|e| value_error("views", e))
}

/// The `depth` argument, of `image`'s size and holding values of `kind`
/// (the library's check, with its message). A disparity is first checked
/// and filled as `mbs-tool mono` reads a disparity file and `extrapolate`
/// takes a disparity array: `inf` marks an unknown pixel, filled from the
/// background side; NaN and negative values are refused.
fn depth_map(value: &Bound<'_, PyAny>, image: &RgbImage, kind: DepthKind) -> PyResult<FloatImage> {
    let mut map = float_map("depth", value)?;
    if map.dimensions() != image.dimensions() {
        return Err(value_error(
            "depth",
            format!(
                "{}x{} pixels, but image is {}x{}",
                map.height(),
                map.width(),
                image.height(),
                image.width()
            ),
        ));
    }
    if kind == DepthKind::Disparity {
        map = checked_disparity(map, image.dimensions(), Path::new("depth"))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
    }
    match kind.problem(&map) {
        Some(problem) => Err(value_error("depth", problem)),
        None => Ok(map),
    }
}

/// The `scale` argument with the settings it takes; a setting given to a
/// scale that does not take it is refused, so that none is silently unused.
fn scaling(
    kind: DepthKind,
    scale: Option<&str>,
    max_disparity: &[f64],
    seed: Integer,
    focal: Option<f64>,
    baseline: Option<f64>,
) -> PyResult<Scaling> {
    let default = if kind == DepthKind::Disparity {
        "as-is"
    } else {
        "range"
    };
    let scale = scale.unwrap_or(default);
    let seed = seed.within("seed", 0..=i128::from(u64::MAX))?;
    if scale != "metric"
        && let Some(name) = [("focal", focal), ("baseline", baseline)]
            .into_iter()
            .find_map(|(name, value)| value.map(|_| name))
    {
        return Err(value_error(
            name,
            format!(
                "only the metric scale takes focal and baseline, not {scale} (give scale=\"metric\")"
            ),
        ));
    }
    match scale {
        "range" => {
            let (low, high) = fractions(max_disparity)?;
            Ok(Scaling::Range { low, high, seed })
        }
        "metric" => Ok(Scaling::Metric {
            focal_px: positive("focal", focal)?,
            baseline_m: positive("baseline", baseline)?,
        }),
        "as-is" => Ok(Scaling::AsIs),
        other => Err(value_error(
            "scale",
            format!("{other:?} is not as-is, metric or range"),
        )),
    }
}

/// The `max_disparity` argument: `(low, high)`, `0 < low <= high < 1`, as
/// `mbs-tool mono --max-disparity LOW:HIGH` takes it.
fn fractions(max_disparity: &[f64]) -> PyResult<(f32, f32)> {
    let &[low, high] = max_disparity else {
        return Err(value_error(
            "max_disparity",
            format!("expected (low, high), got {} values", max_disparity.len()),
        ));
    };
    if !(low > 0.0 && low <= high && high < 1.0) {
        return Err(value_error(
            "max_disparity",
            format!("({low}, {high}): expected fractions of the width with 0 < low <= high < 1"),
        ));
    }
    Ok((low as f32, high as f32))
}

/// A setting of the metric scale: given, finite and positive.
fn positive(name: &str, value: Option<f64>) -> PyResult<f64> {
    match value {
        Some(value) if value.is_finite() && value > 0.0 => Ok(value),
        Some(value) => Err(value_error(
            name,
            format!("{value} is not a positive number"),
        )),
        None => Err(value_error(
            name,
            "the metric scale needs focal and baseline",
        )),
    }
}

/// The set's views (the image at the reference camera) and masks (`None`
/// there) as Python lists.
fn views_and_masks<'py>(
    py: Python<'py>,
    image: RgbImage,
    set: MonoViews,
) -> PyResult<(Bound<'py, PyList>, Bound<'py, PyList>)> {
    let (views, masks) = (PyList::empty(py), PyList::empty(py));
    let mut image = Some(image);
    for view in set.views {
        match view {
            Some(NewView {
                image: synthesised,
                mask,
                ..
            }) => {
                views.append(to_numpy(py, synthesised)?)?;
                masks.append(to_numpy(py, mask)?)?;
            }
            None => {
                let reference = image.take().map(|image| to_numpy(py, image)).transpose()?;
                views.append(reference)?;
                masks.append(py.None())?;
            }
        }
    }
    Ok((views, masks))
}
