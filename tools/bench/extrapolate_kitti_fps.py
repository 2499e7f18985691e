#!/usr/bin/env python3
"""Frames per second of `mbs-tool extrapolate --kitti` on a KITTI-size folder,
against the same job done with numpy and OpenCV, in the same run.

The folder: KITTI 2015's layout (image_2/, image_3/, frames NNNNNN_10.png)
of N frames of 1242x375, each the Middlebury Teddy pair of testdata/ tiled
across from a different offset (real texture, KITTI's size; the true range
is 64 px at this scale, both pipelines search 128 disparities).

mbs: the whole command, `mbs-tool extrapolate --kitti DIR --out OUT
--max-disparity 128` (reads the pairs, matches both views with the built-in
SGM, warps, fills, writes image_1/image_4, masks, disparities, the linked
pair and the manifest), RAYON_NUM_THREADS=2, timed from start to exit.

Peer, per frame, cv2.setNumThreads(2): cv2.imread of both views, StereoSGBM
(3-way, as in extrapolation_vs_opencv.py) for the left view and on the
mirrored pair for the right view, invalid pixels filled from the background
side, the numpy z-buffer splat of both views outwards, cv2.inpaint TELEA,
cv2.imwrite of the two new views and their masks (what a user's script
writes; no manifest, no disparity files, so the peer does less).

Needs numpy and opencv-python-headless (not part of CI) and a release
mbs-tool. From the repository root:

    cargo build --release -p mbs-tool
    python3 tools/bench/extrapolate_kitti_fps.py [--frames 20] [--rounds 2]

Prints each round's seconds and the frames per second of the best round.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from extrapolation_vs_opencv import fill_from_background, sgbm, splat  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TEDDY = ROOT / "testdata" / "middlebury-teddy"
DISPARITIES = 128


def kitti_folder(root, frames):
    """A KITTI 2015 layout of `frames` KITTI-size pairs tiled from Teddy."""
    left, right = cv2.imread(str(TEDDY / "im2.png")), cv2.imread(str(TEDDY / "im6.png"))
    for side in ("image_2", "image_3"):
        (root / side).mkdir(parents=True)
    for k in range(frames):
        offset = 20 * k
        for side, view in (("image_2", left), ("image_3", right)):
            tiled = np.concatenate([view] * 4, axis=1)[:, offset:offset + 1242]
            cv2.imwrite(str(root / side / f"{k:06d}_10.png"), tiled)


def run_mbs(binary, folder, out):
    env = dict(os.environ, RAYON_NUM_THREADS="2")
    start = time.perf_counter()
    subprocess.run([str(binary), "extrapolate", "--kitti", str(folder), "--out", str(out),
                    "--max-disparity", str(DISPARITIES)],
                   check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def run_peer(folder, out, frames):
    out.mkdir(parents=True)
    start = time.perf_counter()
    for k in range(frames):
        name = f"{k:06d}_10.png"
        left = cv2.imread(str(folder / "image_2" / name))
        right = cv2.imread(str(folder / "image_3" / name))
        disp_left = fill_from_background(sgbm(left, right, DISPARITIES))
        mirrored = sgbm(np.ascontiguousarray(right[:, ::-1]), np.ascontiguousarray(left[:, ::-1]), DISPARITIES)
        disp_right = fill_from_background(np.ascontiguousarray(mirrored[:, ::-1]))
        for image, disp, sign, view in ((left, disp_left, 1, "image_1"), (right, disp_right, -1, "image_4")):
            warped, holes = splat(image, disp, sign)
            cv2.imwrite(str(out / f"{view}_{name}"), cv2.inpaint(warped, holes, 3, cv2.INPAINT_TELEA))
            cv2.imwrite(str(out / f"mask_{view}_{name}"), holes)
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=2, help="alternating rounds; the fastest counts")
    parser.add_argument("--mbs-tool", default=str(ROOT / "target" / "release" / "mbs-tool"))
    args = parser.parse_args()
    cv2.setNumThreads(2)
    with tempfile.TemporaryDirectory(prefix="kitti_fps_") as tmp:
        tmp = Path(tmp)
        folder = tmp / "kitti"
        kitti_folder(folder, args.frames)
        mbs_times, peer_times = [], []
        for round_ in range(args.rounds):
            mbs_times.append(run_mbs(args.mbs_tool, folder, tmp / f"mbs{round_}"))
            peer_times.append(run_peer(folder, tmp / f"peer{round_}", args.frames))
            print(f"round {round_ + 1}: mbs {mbs_times[-1]:.2f} s, numpy/OpenCV {peer_times[-1]:.2f} s "
                  f"for {args.frames} frames", flush=True)
        mbs_fps, peer_fps = args.frames / min(mbs_times), args.frames / min(peer_times)
        print("\n| frames | mbs fps | numpy/OpenCV fps | rate ratio |")
        print("| ---: | ---: | ---: | ---: |")
        print(f"| {args.frames} | {mbs_fps:.2f} | {peer_fps:.2f} | **{mbs_fps / peer_fps:.2f}x** |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
