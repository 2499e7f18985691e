//! `mbs._native`: the Rust side of the Python package `mbs` (see
//! `mbs/__init__.py` for the conventions every function follows).
//!
//! Arrays cross as NumPy arrays: images `uint8` HxWx3 RGB, disparity and
//! depth `float32` HxW with `inf` for invalid pixels. A wrong dtype, shape
//! or value is a `ValueError` naming the argument; a file that cannot be
//! read or written is an `OSError` naming it. Heavy calls release the GIL.

mod batches;
mod integer;
mod mono;
mod scoring;
mod synth;

use std::path::{Path, PathBuf};

use image::{ImageBuffer, Pixel, RgbImage};
use mbs_core::FloatImage;
use mbs_core::formats::{carla, exr, pfm, png16, rgb};
use mbs_core::geometry::depth_to_disparity_value;
use mbs_extrapolate::{Disparities, DisparitySource, Extrapolator};
use mbs_infer::StereoMatcher;
use mbs_infer::inpaint::{BackgroundFill, Inpainter, IsotropicFill};
use mbs_infer::{Sgm, SgmConfig, SgmPaths};
use mbs_warp::Dilation;
use numpy::{PyArray2, PyArray3, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::integer::Integer;

/// The most pixels a side an array may have (as the command line's images),
/// and the largest dilation radius.
const MAX_SIDE: usize = 32768;

/// A `ValueError` about argument `name`.
fn value_error(name: &str, problem: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{name}: {problem}"))
}

/// An `OSError` naming `path`.
fn os_error(path: &Path, problem: impl std::fmt::Display) -> PyErr {
    PyOSError::new_err(format!("{}: {problem}", path.display()))
}

/// What an argument that is not the expected array is, for messages.
fn describe(value: &Bound<'_, PyAny>) -> String {
    match value.cast::<numpy::PyUntypedArray>() {
        Ok(array) => format!(
            "a {} array of shape {:?}",
            array.dtype(),
            array.shape().to_vec()
        ),
        Err(_) => match value.get_type().name() {
            Ok(name) => format!("a {name}"),
            Err(_) => "something else".into(),
        },
    }
}

/// Checks an array's sides: at least 1 and at most [`MAX_SIDE`].
fn check_sides(name: &str, height: usize, width: usize) -> PyResult<()> {
    if height == 0 || width == 0 || height > MAX_SIDE || width > MAX_SIDE {
        return Err(value_error(
            name,
            format!("{height}x{width} pixels: each side must be 1 to {MAX_SIDE}"),
        ));
    }
    Ok(())
}

/// A `float32` HxW array as a float image.
fn float_map(name: &str, value: &Bound<'_, PyAny>) -> PyResult<FloatImage> {
    let array = value.cast::<PyArray2<f32>>().map_err(|_| {
        value_error(
            name,
            format!("expected a float32 HxW array, got {}", describe(value)),
        )
    })?;
    let [height, width] = [array.shape()[0], array.shape()[1]];
    check_sides(name, height, width)?;
    let values: Vec<f32> = array.readonly().as_array().iter().copied().collect();
    ImageBuffer::from_raw(width as u32, height as u32, values)
        .ok_or_else(|| value_error(name, "its data does not match its shape"))
}

/// A `uint8` HxWx3 array as an RGB image.
fn rgb_image(name: &str, value: &Bound<'_, PyAny>) -> PyResult<RgbImage> {
    let wrong = || {
        value_error(
            name,
            format!("expected a uint8 HxWx3 RGB array, got {}", describe(value)),
        )
    };
    let array = value.cast::<PyArray3<u8>>().map_err(|_| wrong())?;
    let shape = array.shape();
    if shape[2] != 3 {
        return Err(wrong());
    }
    check_sides(name, shape[0], shape[1])?;
    let values: Vec<u8> = array.readonly().as_array().iter().copied().collect();
    ImageBuffer::from_raw(shape[1] as u32, shape[0] as u32, values)
        .ok_or_else(|| value_error(name, "its data does not match its shape"))
}

/// A matcher's disparity count (0 estimates it from the pair).
fn max_disparity(value: Integer) -> PyResult<u32> {
    value.within(
        "max_disparity",
        0..=i128::from(mbs_infer::sgm::MAX_DISPARITY),
    )
}

/// Checks that the two views of a pair have one size.
fn check_same_size(left: &RgbImage, right: &RgbImage) -> PyResult<()> {
    if left.dimensions() != right.dimensions() {
        return Err(value_error(
            "right",
            format!(
                "{}x{} pixels, but left is {}x{}",
                right.height(),
                right.width(),
                left.height(),
                left.width()
            ),
        ));
    }
    Ok(())
}

/// An image as a NumPy array: HxW for one channel (float32 maps, uint8
/// masks), HxWxC otherwise (uint8 RGB).
fn to_numpy<'py, P>(
    py: Python<'py>,
    image: ImageBuffer<P, Vec<P::Subpixel>>,
) -> PyResult<Bound<'py, PyArrayDyn<P::Subpixel>>>
where
    P: Pixel,
    P::Subpixel: numpy::Element,
{
    let (width, height) = image.dimensions();
    let mut shape = vec![height as usize, width as usize];
    if P::CHANNEL_COUNT > 1 {
        shape.push(usize::from(P::CHANNEL_COUNT));
    }
    numpy::PyArray1::from_vec(py, image.into_raw()).reshape(shape)
}

/// Reads `path` with `read` without the GIL, as a NumPy array; an error
/// is an `OSError` naming the file.
fn read_file<'py, P>(
    py: Python<'py>,
    path: &Path,
    read: impl FnOnce(&Path) -> mbs_core::Result<ImageBuffer<P, Vec<P::Subpixel>>> + Send,
) -> PyResult<Bound<'py, PyArrayDyn<P::Subpixel>>>
where
    P: Pixel + Send,
    P::Subpixel: numpy::Element + Send,
{
    let image = py.detach(|| read(path)).map_err(|e| os_error(path, e))?;
    to_numpy(py, image)
}

/// Writes `path` with `write` without the GIL; an error is an `OSError`
/// naming the file.
fn write_file(
    py: Python<'_>,
    path: &Path,
    write: impl FnOnce(&Path) -> mbs_core::Result<()> + Send,
) -> PyResult<()> {
    py.detach(|| write(path)).map_err(|e| os_error(path, e))
}

/// Reads an image (PNG, PPM, ...) as an RGB array.
///
/// Grey and 16-bit images are converted to 8-bit RGB, alpha is dropped.
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///     The file.
///
/// Returns
/// -------
/// numpy.ndarray
///     ``uint8``, shape ``(H, W, 3)``, RGB.
///
/// Raises
/// ------
/// OSError
///     The file cannot be read or decoded (the message names it).
#[pyfunction]
fn read_rgb(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArrayDyn<u8>>> {
    read_file(py, &path, rgb::read_rgb)
}

/// Writes an RGB array as a PNG.
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///     The file to write: a new file, or a regular file that it replaces.
/// image : numpy.ndarray
///     ``uint8``, shape ``(H, W, 3)``, RGB.
///
/// Raises
/// ------
/// ValueError
///     ``image`` is not such an array (the message begins with ``image:``).
/// OSError
///     The file cannot be written, or is not a regular file (a folder, a
///     device, a FIFO, a socket; it is left as it was); the message names
///     it.
#[pyfunction]
fn write_rgb(py: Python<'_>, path: PathBuf, image: &Bound<'_, PyAny>) -> PyResult<()> {
    let image = rgb_image("image", image)?;
    write_file(py, &path, |path| rgb::write_rgb_png(path, &image))
}

/// Reads a single-channel PFM (disparity or depth).
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///     The file.
///
/// Returns
/// -------
/// numpy.ndarray
///     ``float32``, shape ``(H, W)``; ``inf`` where a pixel has no value.
///
/// Raises
/// ------
/// OSError
///     The file cannot be read or decoded (the message names it).
#[pyfunction]
fn read_pfm(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArrayDyn<f32>>> {
    read_file(py, &path, pfm::read_pfm_grey)
}

/// Writes a disparity or depth map as a little-endian single-channel PFM.
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///     The file to write: a new file, or a regular file that it replaces.
/// map : numpy.ndarray
///     ``float32``, shape ``(H, W)``; every value is kept, ``inf`` and NaN
///     too.
///
/// Raises
/// ------
/// ValueError
///     ``map`` is not such an array (the message begins with ``map:``).
/// OSError
///     The file cannot be written, or is not a regular file (a folder, a
///     device, a FIFO, a socket; it is left as it was); the message names
///     it.
#[pyfunction]
fn write_pfm(py: Python<'_>, path: PathBuf, map: &Bound<'_, PyAny>) -> PyResult<()> {
    let map = float_map("map", map)?;
    write_file(py, &path, |path| {
        pfm::write_pfm_grey(path, &map, pfm::Endian::Little)
    })
}

/// Reads a KITTI 16-bit PNG disparity.
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///     The file.
///
/// Returns
/// -------
/// numpy.ndarray
///     ``float32``, shape ``(H, W)``: each value / 256; 0 (invalid) is
///     ``inf``.
///
/// Raises
/// ------
/// OSError
///     The file cannot be read or decoded (the message names it).
#[pyfunction]
fn read_kitti_disparity(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArrayDyn<f32>>> {
    read_file(py, &path, png16::read_kitti_disparity)
}

/// Writes a disparity as a KITTI 16-bit PNG.
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///     The file to write: a new file, or a regular file that it replaces.
/// disparity : numpy.ndarray
///     ``float32``, shape ``(H, W)``; written as value x 256, with ``inf``,
///     NaN and values that do not fit written as 0 (invalid).
///
/// Raises
/// ------
/// ValueError
///     ``disparity`` is not such an array (the message begins with
///     ``disparity:``).
/// OSError
///     The file cannot be written, or is not a regular file (a folder, a
///     device, a FIFO, a socket; it is left as it was); the message names
///     it.
#[pyfunction]
fn write_kitti_disparity(
    py: Python<'_>,
    path: PathBuf,
    disparity: &Bound<'_, PyAny>,
) -> PyResult<()> {
    let disparity = float_map("disparity", disparity)?;
    write_file(py, &path, |path| {
        png16::write_kitti_disparity(path, &disparity)
    })
}

/// Reads a single-channel OpenEXR depth map.
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///     The file.
///
/// Returns
/// -------
/// numpy.ndarray
///     ``float32``, shape ``(H, W)``.
///
/// Raises
/// ------
/// OSError
///     The file cannot be read or decoded (the message names it).
#[pyfunction]
fn read_exr(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArrayDyn<f32>>> {
    read_file(py, &path, exr::read_exr)
}

/// Writes a depth map as a single-channel OpenEXR file.
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///     The file to write: a new file, or a regular file that it replaces.
/// map : numpy.ndarray
///     ``float32``, shape ``(H, W)``.
///
/// Raises
/// ------
/// ValueError
///     ``map`` is not such an array (the message begins with ``map:``).
/// OSError
///     The file cannot be written, or is not a regular file (a folder, a
///     device, a FIFO, a socket; it is left as it was); the message names
///     it.
#[pyfunction]
fn write_exr(py: Python<'_>, path: PathBuf, map: &Bound<'_, PyAny>) -> PyResult<()> {
    let map = float_map("map", map)?;
    write_file(py, &path, |path| exr::write_exr(path, &map))
}

/// Decodes a CARLA RGB-encoded depth image into metres.
///
/// Parameters
/// ----------
/// rgb : numpy.ndarray
///     ``uint8``, shape ``(H, W, 3)``: the image of CARLA's depth camera.
/// max_depth : float, default 200.0
///     Depth beyond it (m) is ``inf``, as ``mbs-tool decode-depth``'s;
///     positive.
///
/// Returns
/// -------
/// numpy.ndarray
///     ``float32``, shape ``(H, W)``: depth in metres.
///
/// Raises
/// ------
/// ValueError
///     ``rgb`` is not such an array, or ``max_depth`` is not positive (the
///     message begins with the argument's name).
#[pyfunction]
#[pyo3(signature = (rgb, max_depth = 200.0))]
fn decode_carla_depth<'py>(
    py: Python<'py>,
    rgb: &Bound<'py, PyAny>,
    max_depth: f32,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    if max_depth.is_nan() || max_depth <= 0.0 {
        return Err(value_error(
            "max_depth",
            format!("{max_depth} is not positive"),
        ));
    }
    let rgb = rgb_image("rgb", rgb)?;
    let depth =
        py.detach(|| mbs_core::geometry::limit_depth(&carla::decode_depth(&rgb), max_depth));
    to_numpy(py, depth)
}

/// Converts a depth map (m) to disparity (px): ``focal * baseline / depth``.
///
/// For a pair of cameras ``baseline`` metres apart with focal length
/// ``focal`` pixels.
///
/// Parameters
/// ----------
/// depth : numpy.ndarray
///     ``float32``, shape ``(H, W)``, in metres.
/// focal : float
///     The focal length in pixels, positive.
/// baseline : float
///     The distance between the cameras in metres, positive.
/// max_depth : float, default 200.0
///     Depth beyond it (m) gives ``inf``, as depth that is not finite or not
///     positive does.
///
/// Returns
/// -------
/// numpy.ndarray
///     ``float32``, shape ``(H, W)``: disparity in pixels.
///
/// Raises
/// ------
/// ValueError
///     ``depth`` is not such an array, or ``focal`` or ``baseline`` is not a
///     positive number (the message begins with the argument's name).
#[pyfunction]
#[pyo3(signature = (depth, focal, baseline, max_depth = 200.0))]
fn depth_to_disparity<'py>(
    py: Python<'py>,
    depth: &Bound<'py, PyAny>,
    focal: f64,
    baseline: f64,
    max_depth: f32,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    for (name, value) in [("focal", focal), ("baseline", baseline)] {
        if !value.is_finite() || value <= 0.0 {
            return Err(value_error(
                name,
                format!("{value} is not a positive number"),
            ));
        }
    }
    let mut map = float_map("depth", depth)?;
    let scale = focal * baseline;
    py.detach(|| {
        map.iter_mut()
            .for_each(|z| *z = depth_to_disparity_value(*z, scale, max_depth))
    });
    to_numpy(py, map)
}

/// Matches a rectified pair with the built-in semi-global matcher.
///
/// With ``mbs-tool predict``'s defaults.
///
/// Parameters
/// ----------
/// left, right : numpy.ndarray
///     The pair's views, ``uint8``, shape ``(H, W, 3)``, RGB, of one size.
/// max_disparity : int, default 128
///     The number of disparities, 0 to 4096; 0 estimates the range from the
///     pair (up to 256).
/// paths : int, default 5
///     The matcher's paths, 5 or 8.
/// fill : bool, default True
///     Whether holes are filled from the background side (else ``inf``).
///
/// Returns
/// -------
/// numpy.ndarray
///     ``float32``, shape ``(H, W)``: the left view's disparity in pixels.
///
/// Raises
/// ------
/// ValueError
///     A view is not such an array, the views differ in size, or an integer
///     is out of range (the message begins with the argument's name).
/// TypeError
///     An integer argument is not an integer (a float, a bool, a string; the
///     message begins with its name).
#[pyfunction]
#[pyo3(
    signature = (left, right, max_disparity = Integer::of(128), paths = Integer::of(5), fill = true),
    text_signature = "(left, right, max_disparity=128, paths=5, fill=True)"
)]
fn match_stereo<'py>(
    py: Python<'py>,
    left: &Bound<'py, PyAny>,
    right: &Bound<'py, PyAny>,
    max_disparity: Integer,
    paths: Integer,
    fill: bool,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let paths = match paths.within::<u8>("paths", 5..=8)? {
        5 => SgmPaths::Five,
        8 => SgmPaths::Eight,
        other => return Err(value_error("paths", format!("{other} is not 5 or 8"))),
    };
    let max_disparity = self::max_disparity(max_disparity)?;
    let (left, right) = (rgb_image("left", left)?, rgb_image("right", right)?);
    check_same_size(&left, &right)?;
    let matcher = Sgm::new(SgmConfig {
        paths,
        fill,
        ..SgmConfig::with_max_disparity(max_disparity)
    });
    let disparity = py
        .detach(|| matcher.predict(&left, &right))
        .map_err(|e| value_error("left, right", e))?;
    to_numpy(py, disparity.disparity)
}

/// Extrapolates two new views of a rectified pair, as ``mbs-tool extrapolate``.
///
/// With its defaults: ``image_1`` one baseline left of ``left`` and
/// ``image_4`` one baseline right of ``right``, by z-buffered forward warping
/// with the built-in matcher's disparities (tuned for warping), holes grown by
/// ``dilation`` and inpainted.
///
/// Parameters
/// ----------
/// left, right : numpy.ndarray
///     The pair's views, ``uint8``, shape ``(H, W, 3)``, RGB, of one size.
/// max_disparity : int, default 0
///     The matcher's number of disparities, 0 to 4096; 0 estimates the range
///     from the pair.
/// dilation : str, default "none"
///     How holes grow: ``"none"``, ``"square"``, ``"ellipse"``,
///     ``"background-side"`` or ``"foreground-side"``.
/// dilate_radius : int, default 2
///     By how many pixels, 0 to 32768.
/// inpaint : str, default "background"
///     How holes are filled: ``"background"`` or ``"isotropic"``.
/// disparity_left, disparity_right : numpy.ndarray, optional
///     ``float32``, shape ``(H, W)``: disparities (non-negative, or ``inf``
///     where unknown; no NaN) that replace the matcher, as the command's
///     ``--left-disparity``/``--right-disparity`` files; given one, the other
///     view's is derived from it by warping.
///
/// Returns
/// -------
/// dict
///     ``image_1``, ``image_4`` (``uint8``, ``(H, W, 3)``), ``mask_1``,
///     ``mask_4`` (``uint8``, ``(H, W)``, 255 where synthesised) and
///     ``disparity_2``, ``disparity_3`` (``float32``, ``(H, W)``, the
///     disparities used for the left and right views).
///
/// Raises
/// ------
/// ValueError
///     A view or disparity is not such an array or not of the views' size,
///     a disparity has a NaN or negative value, a setting is unknown or out
///     of range (the message begins with the argument's name), or the
///     extrapolation fails (``left, right:``).
/// TypeError
///     An integer argument is not an integer (a float, a bool, a string; the
///     message begins with its name).
#[pyfunction]
#[pyo3(
    signature = (left, right, max_disparity = Integer::of(0), dilation = "none", dilate_radius = Integer::of(2), inpaint = "background", disparity_left = None, disparity_right = None),
    text_signature = "(left, right, max_disparity=0, dilation='none', dilate_radius=2, inpaint='background', disparity_left=None, disparity_right=None)"
)]
#[allow(clippy::too_many_arguments)]
fn extrapolate<'py>(
    py: Python<'py>,
    left: &Bound<'py, PyAny>,
    right: &Bound<'py, PyAny>,
    max_disparity: Integer,
    dilation: &str,
    dilate_radius: Integer,
    inpaint: &str,
    disparity_left: Option<&Bound<'py, PyAny>>,
    disparity_right: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let max_disparity = self::max_disparity(max_disparity)?;
    let dilation = parse_dilation(dilation, dilate_radius)?;
    let inpainter = parse_inpainter(inpaint)?;
    let (left, right) = (rgb_image("left", left)?, rgb_image("right", right)?);
    check_same_size(&left, &right)?;
    let given = |name: &str, value: Option<&Bound<'py, PyAny>>| {
        value
            .map(|v| {
                let map = float_map(name, v)?;
                mbs_extrapolate::disparity::checked_disparity(
                    map,
                    left.dimensions(),
                    Path::new(name),
                )
                .map_err(|e| PyValueError::new_err(e.to_string()))
            })
            .transpose()
    };
    let given = (
        given("disparity_left", disparity_left)?,
        given("disparity_right", disparity_right)?,
    );
    let extrapolator = Extrapolator::new(dilation, inpainter);
    let source = DisparitySource::builtin(max_disparity);
    let (views, disparities) = py
        .detach(|| {
            let disparities = match Disparities::from_maps(given.0, given.1, &left, &right)? {
                Some(disparities) => disparities,
                None => source.disparities(&left, &right)?,
            };
            let views = extrapolator.extrapolate(&left, &right, &disparities)?;
            Ok::<_, mbs_extrapolate::ExtrapolateError>((views, disparities))
        })
        .map_err(|e| value_error("left, right", e))?;
    let out = PyDict::new(py);
    out.set_item("image_1", to_numpy(py, views.image_1)?)?;
    out.set_item("image_4", to_numpy(py, views.image_4)?)?;
    out.set_item("mask_1", to_numpy(py, views.mask_1)?)?;
    out.set_item("mask_4", to_numpy(py, views.mask_4)?)?;
    out.set_item("disparity_2", to_numpy(py, disparities.left)?)?;
    out.set_item("disparity_3", to_numpy(py, disparities.right)?)?;
    Ok(out)
}

/// The `dilation` argument of [`extrapolate`] and [`mono::mono_views`]
/// with its radius, `dilate_radius`.
fn parse_dilation(dilation: &str, radius: Integer) -> PyResult<Dilation> {
    let radius = radius.within("dilate_radius", 0..=MAX_SIDE as i128)?;
    match dilation {
        "none" => Ok(Dilation::None),
        "square" => Ok(Dilation::Square(radius)),
        "ellipse" => Ok(Dilation::Ellipse(radius)),
        "background-side" => Ok(Dilation::BackgroundSide(radius)),
        "foreground-side" => Ok(Dilation::ForegroundSide(radius)),
        other => Err(value_error(
            "dilation",
            format!("{other:?} is not none, square, ellipse, background-side or foreground-side"),
        )),
    }
}

/// The `inpaint` argument of [`extrapolate`] and [`mono::mono_views`].
fn parse_inpainter(inpaint: &str) -> PyResult<Box<dyn Inpainter>> {
    let inpainter: Box<dyn Inpainter> = match inpaint {
        "background" => Box::new(BackgroundFill::default()),
        "isotropic" => Box::new(IsotropicFill),
        other => {
            return Err(value_error(
                "inpaint",
                format!("{other:?} is not background or isotropic"),
            ));
        }
    };
    Ok(inpainter)
}

/// Loads a manifest, checked against the schema and the confinement rule.
///
/// ``mbs.load_manifest`` parses what it returns.
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///     The manifest.
///
/// Returns
/// -------
/// str
///     The manifest as JSON text.
///
/// Raises
/// ------
/// OSError
///     The manifest cannot be read or is not valid (the message names it).
#[pyfunction]
fn load_manifest_json(py: Python<'_>, path: PathBuf) -> PyResult<String> {
    let manifest = py
        .detach(|| mbs_dataset::Manifest::load(&path))
        .map_err(|e| os_error(&path, e))?;
    serde_json::to_string(&manifest).map_err(|e| os_error(&path, e))
}

/// Validates a manifest and its files, as ``mbs-tool validate --json``.
///
/// ``mbs.validate`` parses what it returns.
///
/// Parameters
/// ----------
/// path : str or os.PathLike
///     The manifest.
/// deep : bool, default False
///     Whether every pixel of every file is decoded.
///
/// Returns
/// -------
/// str
///     The command's report as JSON text.
///
/// Raises
/// ------
/// OSError
///     The report cannot be encoded (the message names the manifest).
#[pyfunction]
#[pyo3(signature = (path, deep = false))]
fn validate_json(py: Python<'_>, path: PathBuf, deep: bool) -> PyResult<String> {
    let report = py.detach(|| {
        mbs_dataset::validate::validate_manifest(
            &path,
            mbs_dataset::validate::ValidateOptions { deep },
            &(),
        )
    });
    serde_json::to_string(&report).map_err(|e| os_error(&path, e))
}

/// The native part of ``mbs``, in Rust: use it through ``mbs`` and ``mbs.torch``.
#[pymodule]
fn _native(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_function(wrap_pyfunction!(read_rgb, module)?)?;
    module.add_function(wrap_pyfunction!(write_rgb, module)?)?;
    module.add_function(wrap_pyfunction!(read_pfm, module)?)?;
    module.add_function(wrap_pyfunction!(write_pfm, module)?)?;
    module.add_function(wrap_pyfunction!(read_kitti_disparity, module)?)?;
    module.add_function(wrap_pyfunction!(write_kitti_disparity, module)?)?;
    module.add_function(wrap_pyfunction!(read_exr, module)?)?;
    module.add_function(wrap_pyfunction!(write_exr, module)?)?;
    module.add_function(wrap_pyfunction!(decode_carla_depth, module)?)?;
    module.add_function(wrap_pyfunction!(depth_to_disparity, module)?)?;
    module.add_function(wrap_pyfunction!(match_stereo, module)?)?;
    module.add_function(wrap_pyfunction!(extrapolate, module)?)?;
    module.add_function(wrap_pyfunction!(load_manifest_json, module)?)?;
    module.add_function(wrap_pyfunction!(validate_json, module)?)?;
    module.add_class::<batches::HostBatches>()?;
    module.add_function(wrap_pyfunction!(synth::synth_scene, module)?)?;
    module.add_function(wrap_pyfunction!(scoring::score_json, module)?)?;
    module.add_function(wrap_pyfunction!(scoring::score_folder_json, module)?)?;
    module.add_function(wrap_pyfunction!(mono::mono_views, module)?)?;
    Ok(())
}
