"""The native part of ``mbs``, in Rust: use it through ``mbs`` and ``mbs.torch``."""

# The types of what python/src/*.rs exports. Names, parameters, defaults and
# docstrings (copies of the Rust doc comments, which Python shows) must stay
# those of the built module: tests/test_stubs.py compares them, and the keys
# and dtypes of the typed dicts below with real results.

from os import PathLike
from typing import Literal, SupportsIndex, TypedDict, final

import numpy as np
import numpy.typing as npt
from typing_extensions import TypeAlias

# The order in which python/src/lib.rs registers them.
__all__ = [
    "read_rgb",
    "write_rgb",
    "read_pfm",
    "write_pfm",
    "read_kitti_disparity",
    "write_kitti_disparity",
    "read_exr",
    "write_exr",
    "decode_carla_depth",
    "depth_to_disparity",
    "match_stereo",
    "extrapolate",
    "load_manifest_json",
    "validate_json",
    "HostBatches",
    "synth_scene",
    "score_json",
    "score_folder_json",
    "mono_views",
]

# A file's path: pyo3 takes `str` and `os.PathLike` (`os.fspath` gives `str`).
_Path: TypeAlias = str | PathLike[str]
# An RGB image or a mask: `uint8`, `(H, W, 3)` or `(H, W)`.
_Bytes: TypeAlias = npt.NDArray[np.uint8]
# A disparity or depth map: `float32`, `(H, W)`.
_Map: TypeAlias = npt.NDArray[np.float32]
_Dilation: TypeAlias = Literal["none", "square", "ellipse", "background-side", "foreground-side"]
_Inpaint: TypeAlias = Literal["background", "isotropic"]
_DepthKind: TypeAlias = Literal["metric-depth", "inverse-relative", "disparity"]
_Scale: TypeAlias = Literal["as-is", "metric", "range"]
_Weather: TypeAlias = Literal["ClearNoon", "ClearNight", "ClearSunset", "CloudyNoon", "MidRainyNoon"]

class _Extrapolated(TypedDict):
    """What :func:`extrapolate` returns."""

    image_1: _Bytes
    image_4: _Bytes
    mask_1: _Bytes
    mask_4: _Bytes
    disparity_2: _Map
    disparity_3: _Map

class _SynthScene(TypedDict):
    """What :func:`synth_scene` returns: one entry per camera."""

    views: list[_Bytes]
    depth: list[_Map]
    disparity: list[_Map]

class _MonoViews(TypedDict):
    """What :func:`mono_views` returns: one entry per camera in the lists."""

    views: list[_Bytes]
    masks: list[_Bytes | None]
    disparity: _Map
    drawn_fraction: float | None

class _HostBatch(TypedDict):
    """What :meth:`HostBatches.batch` returns."""

    reference: npt.NDArray[np.float32]
    student_target: npt.NDArray[np.float32]
    teacher_target: npt.NDArray[np.float32]
    ratios: npt.NDArray[np.float64]
    triplets: npt.NDArray[np.int64]
    windows: npt.NDArray[np.int64]
    student_sides: list[Literal["left", "right"]]
    teacher_sides: list[Literal["left", "right"]]
    sample_ids: list[str]
    skipped: list[tuple[str, str]]
    brightness: npt.NDArray[np.float32]
    contrast: npt.NDArray[np.float32]
    saturation: npt.NDArray[np.float32]
    occlusion: npt.NDArray[np.float32]

def read_rgb(path: _Path) -> _Bytes:
    """Reads an image (PNG, PPM, ...) as an RGB array.

    Grey and 16-bit images are converted to 8-bit RGB, alpha is dropped.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    numpy.ndarray
        ``uint8``, shape ``(H, W, 3)``, RGB.

    Raises
    ------
    OSError
        The file cannot be read or decoded (the message names it).
    """

def write_rgb(path: _Path, image: _Bytes) -> None:
    """Writes an RGB array as a PNG.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write: a new file, or a regular file that it replaces.
    image : numpy.ndarray
        ``uint8``, shape ``(H, W, 3)``, RGB.

    Raises
    ------
    ValueError
        ``image`` is not such an array (the message begins with ``image:``).
    OSError
        The file cannot be written, or is not a regular file (a folder, a
        device, a FIFO, a socket; it is left as it was); the message names
        it.
    """

def read_pfm(path: _Path) -> _Map:
    """Reads a single-channel PFM (disparity or depth).

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    numpy.ndarray
        ``float32``, shape ``(H, W)``; ``inf`` where a pixel has no value.

    Raises
    ------
    OSError
        The file cannot be read or decoded (the message names it).
    """

def write_pfm(path: _Path, map: _Map) -> None:
    """Writes a disparity or depth map as a little-endian single-channel PFM.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write: a new file, or a regular file that it replaces.
    map : numpy.ndarray
        ``float32``, shape ``(H, W)``; every value is kept, ``inf`` and NaN
        too.

    Raises
    ------
    ValueError
        ``map`` is not such an array (the message begins with ``map:``).
    OSError
        The file cannot be written, or is not a regular file (a folder, a
        device, a FIFO, a socket; it is left as it was); the message names
        it.
    """

def read_kitti_disparity(path: _Path) -> _Map:
    """Reads a KITTI 16-bit PNG disparity.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    numpy.ndarray
        ``float32``, shape ``(H, W)``: each value / 256; 0 (invalid) is
        ``inf``.

    Raises
    ------
    OSError
        The file cannot be read or decoded (the message names it).
    """

def write_kitti_disparity(path: _Path, disparity: _Map) -> None:
    """Writes a disparity as a KITTI 16-bit PNG.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write: a new file, or a regular file that it replaces.
    disparity : numpy.ndarray
        ``float32``, shape ``(H, W)``; written as value x 256, with ``inf``,
        NaN and values that do not fit written as 0 (invalid).

    Raises
    ------
    ValueError
        ``disparity`` is not such an array (the message begins with
        ``disparity:``).
    OSError
        The file cannot be written, or is not a regular file (a folder, a
        device, a FIFO, a socket; it is left as it was); the message names
        it.
    """

def read_exr(path: _Path) -> _Map:
    """Reads a single-channel OpenEXR depth map.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    numpy.ndarray
        ``float32``, shape ``(H, W)``.

    Raises
    ------
    OSError
        The file cannot be read or decoded (the message names it).
    """

def write_exr(path: _Path, map: _Map) -> None:
    """Writes a depth map as a single-channel OpenEXR file.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write: a new file, or a regular file that it replaces.
    map : numpy.ndarray
        ``float32``, shape ``(H, W)``.

    Raises
    ------
    ValueError
        ``map`` is not such an array (the message begins with ``map:``).
    OSError
        The file cannot be written, or is not a regular file (a folder, a
        device, a FIFO, a socket; it is left as it was); the message names
        it.
    """

def decode_carla_depth(rgb: _Bytes, max_depth: float = 200.0) -> _Map:
    """Decodes a CARLA RGB-encoded depth image into metres.

    Parameters
    ----------
    rgb : numpy.ndarray
        ``uint8``, shape ``(H, W, 3)``: the image of CARLA's depth camera.
    max_depth : float, default 200.0
        Depth beyond it (m) is ``inf``, as ``mbs-tool decode-depth``'s;
        positive.

    Returns
    -------
    numpy.ndarray
        ``float32``, shape ``(H, W)``: depth in metres.

    Raises
    ------
    ValueError
        ``rgb`` is not such an array, or ``max_depth`` is not positive (the
        message begins with the argument's name).
    """

def depth_to_disparity(depth: _Map, focal: float, baseline: float, max_depth: float = 200.0) -> _Map:
    """Converts a depth map (m) to disparity (px): ``focal * baseline / depth``.

    For a pair of cameras ``baseline`` metres apart with focal length
    ``focal`` pixels.

    Parameters
    ----------
    depth : numpy.ndarray
        ``float32``, shape ``(H, W)``, in metres.
    focal : float
        The focal length in pixels, positive.
    baseline : float
        The distance between the cameras in metres, positive.
    max_depth : float, default 200.0
        Depth beyond it (m) gives ``inf``, as depth that is not finite or not
        positive does.

    Returns
    -------
    numpy.ndarray
        ``float32``, shape ``(H, W)``: disparity in pixels.

    Raises
    ------
    ValueError
        ``depth`` is not such an array, or ``focal`` or ``baseline`` is not a
        positive number (the message begins with the argument's name).
    """

def match_stereo(
    left: _Bytes,
    right: _Bytes,
    max_disparity: SupportsIndex = 128,
    paths: SupportsIndex = 5,
    fill: bool = True,
) -> _Map:
    """Matches a rectified pair with the built-in semi-global matcher.

    With ``mbs-tool predict``'s defaults.

    Parameters
    ----------
    left, right : numpy.ndarray
        The pair's views, ``uint8``, shape ``(H, W, 3)``, RGB, of one size.
    max_disparity : int, default 128
        The number of disparities, 0 to 4096; 0 estimates the range from the
        pair (up to 256).
    paths : int, default 5
        The matcher's paths, 5 or 8.
    fill : bool, default True
        Whether holes are filled from the background side (else ``inf``).

    Returns
    -------
    numpy.ndarray
        ``float32``, shape ``(H, W)``: the left view's disparity in pixels.

    Raises
    ------
    ValueError
        A view is not such an array, the views differ in size, or an integer
        is out of range (the message begins with the argument's name).
    TypeError
        An integer argument is not an integer (a float, a bool, a string; the
        message begins with its name).
    """

def extrapolate(
    left: _Bytes,
    right: _Bytes,
    max_disparity: SupportsIndex = 0,
    dilation: _Dilation = "none",
    dilate_radius: SupportsIndex = 2,
    inpaint: _Inpaint = "background",
    disparity_left: _Map | None = None,
    disparity_right: _Map | None = None,
) -> _Extrapolated:
    """Extrapolates two new views of a rectified pair, as ``mbs-tool extrapolate``.

    With its defaults: ``image_1`` one baseline left of ``left`` and
    ``image_4`` one baseline right of ``right``, by z-buffered forward warping
    with the built-in matcher's disparities (tuned for warping), holes grown by
    ``dilation`` and inpainted.

    Parameters
    ----------
    left, right : numpy.ndarray
        The pair's views, ``uint8``, shape ``(H, W, 3)``, RGB, of one size.
    max_disparity : int, default 0
        The matcher's number of disparities, 0 to 4096; 0 estimates the range
        from the pair.
    dilation : str, default "none"
        How holes grow: ``"none"``, ``"square"``, ``"ellipse"``,
        ``"background-side"`` or ``"foreground-side"``.
    dilate_radius : int, default 2
        By how many pixels, 0 to 32768.
    inpaint : str, default "background"
        How holes are filled: ``"background"`` or ``"isotropic"``.
    disparity_left, disparity_right : numpy.ndarray, optional
        ``float32``, shape ``(H, W)``: disparities (non-negative, or ``inf``
        where unknown; no NaN) that replace the matcher, as the command's
        ``--left-disparity``/``--right-disparity`` files; given one, the other
        view's is derived from it by warping.

    Returns
    -------
    dict
        ``image_1``, ``image_4`` (``uint8``, ``(H, W, 3)``), ``mask_1``,
        ``mask_4`` (``uint8``, ``(H, W)``, 255 where synthesised) and
        ``disparity_2``, ``disparity_3`` (``float32``, ``(H, W)``, the
        disparities used for the left and right views).

    Raises
    ------
    ValueError
        A view or disparity is not such an array or not of the views' size,
        a disparity has a NaN or negative value, a setting is unknown or out
        of range (the message begins with the argument's name), or the
        extrapolation fails (``left, right:``).
    TypeError
        An integer argument is not an integer (a float, a bool, a string; the
        message begins with its name).
    """

def load_manifest_json(path: _Path) -> str:
    """Loads a manifest, checked against the schema and the confinement rule.

    ``mbs.load_manifest`` parses what it returns.

    Parameters
    ----------
    path : str or os.PathLike
        The manifest.

    Returns
    -------
    str
        The manifest as JSON text.

    Raises
    ------
    OSError
        The manifest cannot be read or is not valid (the message names it).
    """

def validate_json(path: _Path, deep: bool = False) -> str:
    """Validates a manifest and its files, as ``mbs-tool validate --json``.

    ``mbs.validate`` parses what it returns.

    Parameters
    ----------
    path : str or os.PathLike
        The manifest.
    deep : bool, default False
        Whether every pixel of every file is decoded.

    Returns
    -------
    str
        The command's report as JSON text.

    Raises
    ------
    OSError
        The report cannot be encoded (the message names the manifest).
    """

@final
class HostBatches:
    """The training batches of a run over the ``train`` samples of a manifest.

    As ``mbs-tool train`` draws and decodes them;
    ``mbs.torch.MultiBaselineDataset`` wraps it.

    Parameters
    ----------
    manifest : str or os.PathLike
        The manifest; its ``train`` samples are read, each at least the crop.
    batch_size : int
        Items per batch, 1 to 1024.
    crop_height, crop_width : int
        The crops' sides, 16 to 32768.
    seed : int
        The run's seed, 0 to ``2**64 - 1``.
    augment_json : str, default "{}"
        A JSON object of ``trainer.augment``-style keys; missing ones take the
        paper's values, unknown ones are refused.

    Raises
    ------
    OSError
        The manifest cannot be used, or a sample is smaller than the crop (the
        message names the manifest).
    ValueError
        A setting is out of range or unknown (the message begins with its
        name).
    TypeError
        An integer argument is not an integer (the message begins with its
        name).
    """

    def __new__(
        cls,
        manifest: _Path,
        batch_size: SupportsIndex,
        crop_height: SupportsIndex,
        crop_width: SupportsIndex,
        seed: SupportsIndex,
        augment_json: str = "{}",
    ) -> HostBatches: ...
    def batch(self, step: SupportsIndex) -> _HostBatch:
        """Draws and decodes the batch of a step.

        Parameters
        ----------
        step : int
            The step, 0 to ``2**32 - 1``.

        Returns
        -------
        dict
            NumPy arrays and lists: the clean crops ``reference``,
            ``student_target`` and ``teacher_target`` (``float32``,
            ``[B, 3, H, W]`` in ``[0, 1]``), ``ratios`` (``float64``,
            ``[B]``), ``triplets`` (``int64``, ``[B, 3]``: reference, student
            and teacher view), ``windows`` (``int64``, ``[B, 2]``: top and
            left of the crop), ``student_sides`` and ``teacher_sides``
            (``"left"``/``"right"``), ``sample_ids``, ``skipped`` (unreadable
            images met and replaced, each ``(path, error)``), and the
            augmentation's draws: ``brightness``, ``contrast``,
            ``saturation`` (``float32``, ``[B]``) and ``occlusion``
            (``float32``, ``[B, 1, H, W]``, 1 where the target is erased).

        Raises
        ------
        OSError
            The batch cannot be read (the message names the manifest).
        ValueError
            ``step`` is out of range.
        TypeError
            ``step`` is not an integer.
        """

def synth_scene(
    seed: SupportsIndex = 0,
    views: SupportsIndex = 5,
    width: SupportsIndex = 192,
    height: SupportsIndex = 96,
    focal: float = 96.0,
    baseline: float = 0.5,
    weather: _Weather = "ClearNoon",
    supersample: SupportsIndex = 2,
) -> _SynthScene:
    """Renders a procedural street scene with exact ground truth.

    A scene generated from ``seed``, rendered by exact ray casting from a rig
    of ``views`` cameras ``baseline`` metres apart (camera ``k`` at ``x = k *
    baseline``) with the principal point at the centre, as ``mbs-tool synth``
    renders its frames.

    Parameters
    ----------
    seed : int, default 0
        The scene's seed, 0 to ``2**64 - 1``: a seed gives the same scene
        every time.
    views : int, default 5
        The number of cameras, 2 to 16.
    width : int, default 192
        Each view's width in pixels, 8 to 4096.
    height : int, default 96
        Each view's height in pixels, 8 to 4096; all views together have at
        most ``2**26`` pixels.
    focal : float, default 96.0
        The focal length in pixels, positive.
    baseline : float, default 0.5
        The distance between neighbouring cameras in metres, positive.
    weather : str, default "ClearNoon"
        ``"ClearNoon"``, ``"ClearNight"``, ``"ClearSunset"``, ``"CloudyNoon"``
        or ``"MidRainyNoon"``.
    supersample : int, default 2
        ``supersample**2`` samples per pixel, 1 to 4.

    Returns
    -------
    dict
        Lists with one entry per camera: ``views`` (``uint8``, ``(H, W,
        3)``), ``depth`` (``float32``, ``(H, W)``, planar metres; the sky is
        1000 m) and ``disparity`` (``float32``, ``(H, W)``, ``focal *
        baseline / depth``: the exact disparity of a one-baseline pair; ``k``
        times it for cameras ``k`` apart).

    Raises
    ------
    ValueError
        A setting is out of range or unknown (the message begins with its
        name).
    TypeError
        An integer argument is not an integer (a float, a bool, a string; the
        message begins with its name).
    """

_Protocol: TypeAlias = Literal["pixels", "s3", "raft-stereo", "igev-stereo", "kitti", "eth3d", "middlebury"]
_Benchmark: TypeAlias = Literal["kitti", "middlebury", "eth3d", "drivingstereo", "sceneflow"]
_Dataset: TypeAlias = Literal["kitti2015", "kitti2012", "middlebury", "eth3d", "drivingstereo", "sceneflow", "other"]

def score_json(
    prediction: _Map,
    gt: _Map,
    *,
    noc: _Bytes | None = None,
    protocol: _Protocol = "s3",
    dataset: _Dataset = "other",
    disparity_bound: SupportsIndex | None = None,
    thresholds: list[float] | None = None,
    name: str = "image",
) -> str:
    """Scores a predicted disparity against its ground truth under a protocol.

    As ``mbs-tool eval PRED --gt GT [--noc MASK] --protocol P --json``;
    ``mbs.score`` parses what it returns.

    Parameters
    ----------
    prediction : numpy.ndarray
        The predicted disparity (``float32``, ``(H, W)``, ``inf`` where the
        network gave none).
    gt : numpy.ndarray
        The ground truth (``float32``, ``(H, W)``, ``inf`` where unknown).
    noc : numpy.ndarray, optional
        The non-occluded mask (``uint8``, ``(H, W)``, non-zero where the
        pixel is visible in the other view); NOC and OCC need it.
    protocol : str, default "s3"
        ``pixels``, ``s3``, ``raft-stereo``, ``igev-stereo``, ``kitti``,
        ``eth3d`` or ``middlebury`` (docs/evaluation.md).
    dataset : str, default "other"
        Whose rules the protocol applies: ``kitti2015``, ``kitti2012``,
        ``middlebury``, ``eth3d``, ``drivingstereo``, ``sceneflow`` or
        ``other``.
    disparity_bound : int, optional
        The scene's disparity bound (Middlebury's ``ndisp``).
    thresholds : list of float, optional
        Out-x thresholds in pixels (default: 1, 2, 3 under ``pixels``,
        the protocol's own otherwise).
    name : str, default "image"
        The image's name in the report.

    Returns
    -------
    str
        The command's report as JSON text.

    Raises
    ------
    ValueError
        An unknown protocol or dataset, a protocol with no rules for the
        dataset, a wrong array, a ground truth with no valid pixel, or a
        prediction the rules cannot score (the message names the argument).
    """

def score_folder_json(
    predictions: _Path,
    benchmark: _Benchmark,
    folder: _Path,
    *,
    protocol: _Protocol = "s3",
    frames: list[str] | None = None,
    thresholds: list[float] | None = None,
) -> str:
    """Scores a folder of predictions against a benchmark folder's ground truth.

    As ``mbs-tool eval PREDICTIONS --BENCHMARK FOLDER [--frames FILE]
    --protocol P --json``; ``mbs.score_folder`` parses what it returns.

    Parameters
    ----------
    predictions : str or os.PathLike
        The folder of predictions, one ``<frame>.pfm``, ``.png`` or ``.exr``
        per pair (KITTI ``000000_10``, a Middlebury or ETH3D scene...).
    benchmark : str
        The folder's layout, as ``eval``'s flag names it: ``kitti``,
        ``middlebury``, ``eth3d``, ``drivingstereo`` or ``sceneflow``.
    folder : str or os.PathLike
        The benchmark folder (e.g. ``kitti2015/training``,
        ``MiddEval3/trainingH``).
    protocol : str, default "s3"
        ``pixels``, ``s3``, ``raft-stereo``, ``igev-stereo``, ``kitti``,
        ``eth3d`` or ``middlebury``.
    frames : list of str, optional
        Score only these frames (each must be one of the folder's).
    thresholds : list of float, optional
        Out-x thresholds in pixels (default: 1, 2, 3 under ``pixels``,
        the protocol's own otherwise).

    Returns
    -------
    str
        The command's report as JSON text, with ``failed``: each image that
        could not be scored, as ``[name, reason]``.

    Raises
    ------
    ValueError
        An unknown benchmark or protocol, a protocol with no rules for the
        benchmark, an empty frame list, or wrong thresholds.
    OSError
        The folder is off its layout, a listed frame is not one of its
        frames, or no image could be scored.
    """

def mono_views(
    image: _Bytes,
    depth: _Map,
    kind: _DepthKind,
    *,
    views: SupportsIndex = 4,
    reference: SupportsIndex = 1,
    scale: _Scale | None = None,
    max_disparity: tuple[float, float] = (0.05, 0.15),
    seed: SupportsIndex = 0,
    sample_id: str = "",
    focal: float | None = None,
    baseline: float | None = None,
    dilation: _Dilation = "none",
    dilate_radius: SupportsIndex = 2,
    inpaint: _Inpaint = "background",
) -> _MonoViews:
    """The views of a virtual rig from one image and its depth or disparity.

    For a depth network of your own (a single-image *Learning Stereo from
    Single Images* set): the map becomes one baseline's disparity of a
    virtual rig (``scale``), and every camera but the image's is the image
    forward-warped by ``|k - reference|`` times that disparity, its holes
    grown by ``dilation`` and inpainted, as :func:`extrapolate` makes its
    views.

    Parameters
    ----------
    image : numpy.ndarray
        ``uint8``, shape ``(H, W, 3)``, RGB.
    depth : numpy.ndarray
        ``float32``, shape ``(H, W)``: the image's map, of kind ``kind``;
        every value finite, but that a disparity may have ``inf`` where
        unknown (filled from the background side, as :func:`extrapolate`
        and ``mbs-tool mono`` fill it).
    kind : str
        What ``depth`` holds: ``"metric-depth"`` (metres, positive),
        ``"inverse-relative"`` (inverse depth up to scale and shift, as
        MiDaS or relative Depth Anything give) or ``"disparity"`` (pixels,
        non-negative).
    views : int, default 4
        The number of cameras, one baseline apart, 2 to 64.
    reference : int, default 1
        The image's camera, 0 to ``views - 1`` (the default is the paper's:
        one camera left of the image, two right).
    scale : str, optional
        How the map becomes one baseline's disparity: ``"as-is"`` (a
        disparity in pixels, kind ``"disparity"`` only), ``"metric"``
        (``focal * baseline / depth``, kind ``"metric-depth"`` only) or
        ``"range"`` (any kind: the map as inverse depth, shifted so that its
        least value is 0 if negative, scaled so that its largest is a fraction
        of the width drawn from ``max_disparity``). The default is
        ``"as-is"`` for a disparity, ``"range"`` otherwise.
    max_disparity : tuple of float, default (0.05, 0.15)
        With ``"range"``: ``(low, high)``, the largest disparity is a
        fraction of the width drawn uniformly from it per image, from
        ``seed`` and ``sample_id`` only; ``0 < low <= high < 1``.
    seed : int, default 0
        The draw's seed, 0 to ``2**64 - 1``.
    sample_id : str, default ""
        The image's id in the draw (``mbs-tool`` uses its file stem).
    focal, baseline : float, optional
        With ``"metric"`` (and only then): the virtual rig's focal length in
        pixels and baseline in metres, positive.
    dilation : str, default "none"
        How holes grow: ``"none"``, ``"square"``, ``"ellipse"``,
        ``"background-side"`` or ``"foreground-side"``.
    dilate_radius : int, default 2
        By how many pixels, 0 to 32768.
    inpaint : str, default "background"
        How holes are filled: ``"background"`` or ``"isotropic"``.

    Returns
    -------
    dict
        ``views``: one ``uint8`` ``(H, W, 3)`` array per camera (``image``
        itself at ``reference``); ``masks``: per camera, ``None`` at
        ``reference``, else ``uint8`` ``(H, W)``, 255 where synthesised;
        ``disparity``: ``float32`` ``(H, W)``, the image's disparity against
        a camera one baseline away (camera ``k`` is warped by ``|k -
        reference|`` times it); ``drawn_fraction``: with ``"range"``, the
        drawn largest disparity as a fraction of the width, else ``None``.

    Raises
    ------
    ValueError
        An array is not as above or the two differ in size, the map has a
        value its kind cannot hold (NaN; ``inf`` but in a disparity; a depth
        of zero or below; a negative disparity; one value only, or none
        known), a setting is unknown, out of range or not allowed with the
        kind or scale, or every pixel of a view would be synthesised (the
        message begins with the argument's name).
    TypeError
        An integer argument is not an integer (the message begins with its
        name).

    Example::

        depth = my_network(image)                     # your PyTorch model's float32 HxW
        rig = mbs.mono_views(image, depth, "inverse-relative", seed=7, sample_id="0001")
        left, image, right, far_right = rig["views"]  # the paper's four cameras
        synthesised = rig["masks"][2]                 # 255 where right was inpainted
    """
