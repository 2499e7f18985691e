"""mbs from Python: stereo files, CARLA depth, the built-in matcher and more.

Disparity and depth files, CARLA depth, the built-in matcher, extrapolation,
the views of a virtual rig from one image and your own network's depth,
procedural scenes with exact ground truth, manifests (and in ``mbs.torch``,
S3 for PyTorch networks). The package is typed (``py.typed``, with stubs for
its native module).

Conventions, the same for every function:

- images are ``uint8`` arrays of shape ``(H, W, 3)``, RGB;
- disparity and depth are ``float32`` arrays of shape ``(H, W)``, with
  ``inf`` where a pixel has no valid value;
- a wrong dtype, shape or value raises ``ValueError`` naming the argument;
  a file that cannot be read or written raises ``OSError`` naming it;
- heavy calls release the GIL, so threads run them in parallel.

Example::

    import numpy as np, mbs
    depth = mbs.decode_carla_depth(rgb)                   # metres, inf past 200 m
    disparity = mbs.depth_to_disparity(depth, focal=480.0, baseline=0.5)
    mbs.write_kitti_disparity("disp.png", disparity)
    predicted = mbs.match_stereo(left, right, max_disparity=128)
    views = mbs.extrapolate(left, right)                  # image_1, image_4, masks, disparities
    rig = mbs.mono_views(image, net(image), "inverse-relative")  # views, masks from one image
    scene = mbs.synth_scene(seed=3, views=5)              # views, depth, disparity per camera
    report = mbs.score(predicted, gt)                     # the S3 paper's protocol, as eval
"""

import json as _json
from os import PathLike as _PathLike
from typing import Any as _Any
from typing import Union as _Union

from mbs import _native
from mbs._native import (
    decode_carla_depth,
    depth_to_disparity,
    extrapolate,
    match_stereo,
    mono_views,
    read_exr,
    read_kitti_disparity,
    read_pfm,
    read_rgb,
    synth_scene,
    write_exr,
    write_kitti_disparity,
    write_pfm,
    write_rgb,
)


def load_manifest(path: _Union[str, _PathLike[str]]) -> dict[str, _Any]:
    """Load a dataset manifest, checked against the schema and the confinement rule.

    Parameters
    ----------
    path : str or os.PathLike
        The manifest (JSON); its paths are relative to its folder, and
        confined to it.

    Returns
    -------
    dict
        The manifest: ``rig``, ``samples``, ``provenance`` and the rest of
        its schema.

    Raises
    ------
    OSError
        The manifest cannot be read or is not valid (the message names it).
    """
    manifest: dict[str, _Any] = _json.loads(_native.load_manifest_json(path))
    return manifest


def validate(path: _Union[str, _PathLike[str]], deep: bool = False) -> dict[str, _Any]:
    """Validate a manifest and its files, as ``mbs-tool validate --json``.

    Parameters
    ----------
    path : str or os.PathLike
        The manifest.
    deep : bool, default False
        Whether every pixel of every file is decoded.

    Returns
    -------
    dict
        The command's report: ``manifest``, ``deep``, ``samples``,
        ``files_checked`` and ``problems`` (each with its ``kind``,
        ``message`` and, where it has them, ``sample`` and ``path``). The
        manifest is clean when ``problems`` is empty; a manifest that
        cannot be read is a problem of the report, not an exception.

    Raises
    ------
    OSError
        The report cannot be encoded (it names the manifest).
    """
    report: dict[str, _Any] = _json.loads(_native.validate_json(path, deep))
    return report


def score(
    prediction: _Any,
    gt: _Any,
    *,
    noc: _Any = None,
    protocol: str = "s3",
    dataset: str = "other",
    disparity_bound: _Union[int, None] = None,
    thresholds: _Union[list[float], None] = None,
    name: str = "image",
) -> dict[str, _Any]:
    """Score a predicted disparity against its ground truth under a protocol.

    As ``mbs-tool eval PRED --gt GT [--noc MASK] --protocol P --json``, with
    the same figures to the last digit: the scoring is ``mbs-eval``'s, as
    ``eval``, ``benchmark`` and the trainer's validation use it. The default
    protocol is the S3 paper's (``s3``: per image, ground truth in
    ``(0, 191)``), the figures a paper compares with; ``eval``'s own default
    is ``pixels`` (every valid pixel, pooled).

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
        Out-x thresholds in pixels (default: 1, 2, 3 under ``pixels``, the
        protocol's own otherwise).
    name : str, default "image"
        The image's name in the report.

    Returns
    -------
    dict
        The command's JSON report: ``protocol``, ``dataset``, ``rules``,
        ``headline``, ``images`` (the image's figures by region) and
        ``score`` (``ALL``, and ``NOC``/``OCC`` with a mask: ``epe``,
        ``out1``... as the rules name them, ``density``, ``images``);
        under ``pixels``, ``eval``'s pooled report.

    Raises
    ------
    ValueError
        An unknown protocol or dataset, a protocol with no rules for the
        dataset, a wrong array, a ground truth with no valid pixel, or a
        prediction the rules cannot score (the message names the argument).

    Example::

        report = mbs.score(predicted, gt, noc=mask)      # the S3 paper's protocol
        print(report["score"]["ALL"]["epe"], report["score"]["NOC"]["out3"])
    """
    report: dict[str, _Any] = _json.loads(
        _native.score_json(
            prediction,
            gt,
            noc=noc,
            protocol=protocol,  # type: ignore[arg-type]
            dataset=dataset,  # type: ignore[arg-type]
            disparity_bound=disparity_bound,
            thresholds=thresholds,
            name=name,
        )
    )
    return report


def score_folder(
    predictions: _Union[str, _PathLike[str]],
    benchmark: str,
    folder: _Union[str, _PathLike[str]],
    *,
    protocol: str = "s3",
    frames: _Union[list[str], None] = None,
    thresholds: _Union[list[float], None] = None,
) -> dict[str, _Any]:
    """Score a folder of predictions against a benchmark folder's ground truth.

    As ``mbs-tool eval PREDICTIONS --BENCHMARK FOLDER [--frames FILE]
    --protocol P --json``, with the same figures; the default protocol is
    the S3 paper's, as ``mbs.score``'s (``eval``'s own default is
    ``pixels``).

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
        Out-x thresholds in pixels (default: 1, 2, 3 under ``pixels``, the
        protocol's own otherwise).

    Returns
    -------
    dict
        The command's JSON report (as :func:`score`'s, over the folder's
        images, with ``unscored``: the frames without ground truth), and
        ``failed``: each image that could not be scored, as ``[name,
        reason]``; the others are scored.

    Raises
    ------
    ValueError
        An unknown benchmark or protocol, a protocol with no rules for the
        benchmark, an empty frame list, or wrong thresholds.
    OSError
        The folder is off its layout, a listed frame is not one of its
        frames, or no image could be scored.

    Example::

        report = mbs.score_folder("pred/", "kitti", "kitti2015/training")
        print(report["score"]["ALL"]["out3"])            # the paper's KITTI 2015 figure
    """
    report: dict[str, _Any] = _json.loads(
        _native.score_folder_json(
            predictions,
            benchmark,  # type: ignore[arg-type]
            folder,
            protocol=protocol,  # type: ignore[arg-type]
            frames=frames,
            thresholds=thresholds,
        )
    )
    return report


__all__ = [
    "decode_carla_depth",
    "depth_to_disparity",
    "extrapolate",
    "load_manifest",
    "match_stereo",
    "mono_views",
    "read_exr",
    "read_kitti_disparity",
    "read_pfm",
    "read_rgb",
    "score",
    "score_folder",
    "synth_scene",
    "validate",
    "write_exr",
    "write_kitti_disparity",
    "write_pfm",
    "write_rgb",
]
