#!/usr/bin/env python3
"""Extrapolation quality on real scenes: mbs against a careful numpy/OpenCV pipeline.

The same tasks for both: every pair of views one or two steps apart in the
real multi-view scenes of testdata/ (Middlebury Tsukuba, Baby2, Bowling2,
Laundry) is extrapolated one baseline outwards on each side, and each new
view is scored against the real view there (PSNR and SSIM over all pixels,
PSNR over the pixels each pipeline synthesised). mbs runs the
`extrapolation_eval` example with `--json` (the defaults of `mbs-tool
extrapolate`: built-in SGM for both views, forward warp, background fill).

Peer, per pair:
- disparity: OpenCV StereoSGBM (3-way, blockSize 5, P1 = 8*3*5^2,
  P2 = 32*3*5^2, disp12MaxDiff 1, uniqueness 10, speckles 100 / 2) for the
  left view, and on the mirrored pair for the right view; numDisparities is
  the scene's true largest disparity (from its ground truth, see
  testdata/README.md) plus 10 %, rounded up to 16, which the peer is given
  and mbs estimates; invalid pixels are filled from the background side
  (the smaller neighbour along the row);
- warp: sub-pixel splatting of each pixel to its two nearest target
  columns with linear weights and a z-buffer (contributions within 1 px of
  the nearest disparity are blended);
- fill: cv2.inpaint TELEA, radius 3, over the pixels nothing landed on.
SSIM is the Gaussian 11x11, sigma 1.5 form of mbs_image::quality::ssim.

Needs numpy and opencv-python-headless (not a CI dependency). From the
repository root:

    python3 tools/bench/extrapolation_vs_opencv.py [--num-disparities N]

`--num-disparities N` gives the peer one fixed range for every pair instead
(a multiple of 16), as a user who does not know each scene's range would.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from extrapolate_vs_numpy import psnr, read_rgb, ssim  # noqa: E402

TESTDATA = os.path.join(os.path.dirname(__file__), "../../testdata")

# (name, view paths left to right, largest true disparity per view step in px)
SCENES = [
    ("Tsukuba", [f"middlebury-tsukuba-row3/scene1.row3.col{k}.ppm" for k in range(1, 6)], 15.0),
    ("Baby2", [f"middlebury-baby2/view{k}.png" for k in range(7)], 155 / 12),
    ("Bowling2", [f"middlebury-bowling2/view{k}.png" for k in range(7)], 199 / 12),
    ("Laundry", [f"middlebury-laundry/view{k}.png" for k in range(7)], 232 / 12),
]


def sgbm(left, right, num_disparities):
    matcher = cv2.StereoSGBM_create(
        0, num_disparities, 5, P1=8 * 3 * 25, P2=32 * 3 * 25, disp12MaxDiff=1,
        uniquenessRatio=10, speckleWindowSize=100, speckleRange=2, mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    return matcher.compute(left, right).astype(np.float32) / 16


def fill_from_background(disp):
    """Each run of invalid (negative) values takes the smaller valid neighbour along its row."""
    out = disp.copy()
    width = out.shape[1]
    index = np.arange(width)
    for row in out:
        bad = row < 0
        if bad.all():
            row[:] = 0
            continue
        left = np.maximum.accumulate(np.where(~bad, index, -1))
        right = np.minimum.accumulate(np.where(~bad, index, width)[::-1])[::-1]
        left_value = np.where(left >= 0, row[np.clip(left, 0, None)], np.inf)
        right_value = np.where(right < width, row[np.clip(right, None, width - 1)], np.inf)
        row[bad] = np.minimum(left_value, right_value)[bad]
    return out


def splat(image, disp, sign, same_surface=1.0):
    """Sub-pixel forward warp x -> x + sign * d with a z-buffer; returns the view and its holes."""
    h, w = disp.shape
    x = np.arange(w)[None, :] + sign * disp
    x0 = np.floor(x).astype(np.int64)
    frac = x - x0
    rows = np.repeat(np.arange(h)[:, None], w, 1)
    zbuf = np.full(h * w, -np.inf)
    taps = []
    for offset, weight in ((0, 1 - frac), (1, frac)):
        tx = x0 + offset
        ok = (tx >= 0) & (tx < w) & (weight > 1e-3)
        target = (rows * w + tx)[ok]
        np.maximum.at(zbuf, target, disp[ok])
        taps.append((target, ok, weight[ok]))
    colour = np.zeros((h * w, 3))
    weights = np.zeros(h * w)
    for target, ok, weight in taps:
        front = disp[ok] >= zbuf[target] - same_surface
        np.add.at(colour, target[front], image[ok][front] * weight[front, None])
        np.add.at(weights, target[front], weight[front])
    holes = weights < 1e-3
    out = np.where(holes[:, None], 0, colour / np.maximum(weights, 1e-9)[:, None])
    out = np.clip(np.rint(out), 0, 255).astype(np.uint8).reshape(h, w, 3)
    return out, (holes * 255).astype(np.uint8).reshape(h, w)


def peer_scene(views, max_disparity, step, fixed_range=None):
    """Scores of the peer's new views: (psnr_all, ssim_all, psnr_synthesised, synthesised) each."""
    num = fixed_range or int(np.ceil(1.1 * step * max_disparity / 16)) * 16
    scores = []
    for k in range(step, len(views) - 2 * step):
        left, right = views[k], views[k + step]
        disp_left = fill_from_background(sgbm(left, right, num))
        mirrored = sgbm(np.ascontiguousarray(right[:, ::-1]), np.ascontiguousarray(left[:, ::-1]), num)
        disp_right = fill_from_background(np.ascontiguousarray(mirrored[:, ::-1]))
        for image, disp, sign, target in ((left, disp_left, 1, k - step), (right, disp_right, -1, k + 2 * step)):
            warped, holes = splat(image, disp, sign)
            new = cv2.inpaint(warped, holes, 3, cv2.INPAINT_TELEA)
            real = views[target]
            scores.append((psnr(new, real), ssim(new, real), psnr(new, real, holes) if holes.any() else np.nan,
                           (holes > 0).mean()))
    return scores


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--num-disparities", type=int, default=None,
                        help="one SGBM range for every pair (default: each scene's true range + 10 %%)")
    args = parser.parse_args()
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "mbs-extrapolate", "--example", "extrapolation_eval"],
                   check=True)
    binary = os.path.join(os.path.dirname(__file__), "../../target/release/examples/extrapolation_eval")
    start = time.perf_counter()
    done = subprocess.run([binary, "--json"], check=True, capture_output=True, text=True)
    mbs_seconds = time.perf_counter() - start
    mbs = json.loads(done.stdout.strip().splitlines()[-1])

    cv2.setNumThreads(2)
    scenes = [(name, [read_rgb(os.path.join(TESTDATA, p)) for p in paths], top) for name, paths, top in SCENES]
    start = time.perf_counter()
    peer = {step: {name: peer_scene(views, top, step, args.num_disparities) for name, views, top in scenes} for step in (1, 2)}
    peer_seconds = time.perf_counter() - start

    print(f"mbs {mbs_seconds:.1f} s, peer {peer_seconds:.1f} s for the same views (both steps, "
          f"disparity included; mbs's time includes reading the scenes)\n")
    for step in (1, 2):
        print(f"Pairs {step} view{'s' if step > 1 else ''} apart:\n")
        print("| scene | views | mbs PSNR all | peer PSNR all | difference (dB) | mbs SSIM | peer SSIM "
              "| mbs PSNR synthesised | peer PSNR synthesised | mbs synthesised | peer synthesised |")
        print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
        rows, all_peer = [], []
        for name, _, _ in scenes:
            scores = peer[step][name]
            if not scores:
                continue
            all_peer += scores
            rows.append((name, mbs[f"step{step}"][name], np.nanmean(np.array(scores), 0), len(scores)))
        views = sum(r[3] for r in rows)
        mean = {key: sum(r[1][key] * r[3] for r in rows) / views
                for key in ("psnr_all", "ssim_all", "psnr_synthesised", "synthesised")}
        rows.append(("mean", mean, np.nanmean(np.array(all_peer), 0), views))
        for name, ours, theirs, count in rows:
            print(f"| {name} | {count} | {ours['psnr_all']:.2f} | {theirs[0]:.2f} | "
                  f"**{ours['psnr_all'] - theirs[0]:+.2f}** | {ours['ssim_all']:.3f} | {theirs[1]:.3f} | "
                  f"{ours['psnr_synthesised']:.2f} | {theirs[2]:.2f} | {100 * ours['synthesised']:.1f} % | "
                  f"{100 * theirs[3]:.1f} % |")
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
