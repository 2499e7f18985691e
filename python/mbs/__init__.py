"""mbs from Python: disparity and depth files, CARLA depth, the built-in matcher,
extrapolation, procedural scenes with exact ground truth, manifests (and in
``mbs.torch``, S3 for PyTorch networks).

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
    scene = mbs.synth_scene(seed=3, views=5)              # views, depth, disparity per camera
"""

import json as _json

from mbs import _native
from mbs._native import (
    decode_carla_depth,
    depth_to_disparity,
    extrapolate,
    match_stereo,
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


def load_manifest(path):
    """A dataset manifest as a dict (rig, samples, provenance), checked
    against the schema and the confinement rule of its paths, which are
    relative to the manifest's folder. ``OSError`` names a manifest that
    cannot be read or is not valid."""
    return _json.loads(_native.load_manifest_json(path))


def validate(path, deep=False):
    """``mbs-tool validate --json``'s report as a dict: ``manifest``,
    ``deep``, ``samples``, ``files_checked`` and ``problems`` (each with its
    ``kind``, ``message`` and, where it has them, ``sample`` and ``path``).
    The manifest is clean when ``problems`` is empty; ``deep`` decodes every
    pixel of every file."""
    return _json.loads(_native.validate_json(path, deep))


__all__ = [
    "decode_carla_depth",
    "depth_to_disparity",
    "extrapolate",
    "load_manifest",
    "match_stereo",
    "read_exr",
    "read_kitti_disparity",
    "read_pfm",
    "read_rgb",
    "synth_scene",
    "validate",
    "write_exr",
    "write_kitti_disparity",
    "write_pfm",
    "write_rgb",
]
