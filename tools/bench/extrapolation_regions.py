#!/usr/bin/env python3
"""Where the error of mbs's extrapolated views lies, region by region (issue 42).

The tasks of extrapolation_vs_opencv.py: every pair of views one or two
steps apart in the real multi-view scenes of testdata/ is extrapolated one
baseline outwards on each side by `mbs-tool extrapolate` with its defaults,
and each new view's squared error against the real view there is split
into four regions:

  a  the border strip the new camera moves into: per row, the columns
     before the first column any source pixel lands on (a source pixel
     with a disparity of at least 0.5 px; the matcher leaves about 0 in
     some border columns, whose pixels land unshifted), with the run of
     synthesised (masked) pixels from that edge;
  b  the other synthesised pixels: disocclusions inside the image;
  c  depth edges: visible pixels within --edge-band px of a jump of at
     least --edge-jump px between neighbouring pixels of the estimated
     disparity, forward-warped into the new view (nearest column,
     z-buffered, holes filled from the background side);
  d  the other visible pixels.

For each region it prints its share of the pixels and of the squared
error, and the view's PSNR if the region were perfect: where a gain of
1 dB could come from. Needs numpy and opencv-python-headless (not a CI
dependency) and a built mbs-tool. From the repository root:

    python3 tools/bench/extrapolation_regions.py --mbs-tool target/release/mbs-tool [--json FILE]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from extrapolate_vs_numpy import psnr, read_pfm, read_rgb  # noqa: E402
from extrapolation_vs_opencv import SCENES, TESTDATA  # noqa: E402

REGIONS = "abcd"


def forward_warp(disp, sign):
    """The largest disparity landing on each column of the new view (x + sign d), NaN where none."""
    h, w = disp.shape
    out = np.full((h, w), -np.inf)
    ys, xs = np.mgrid[0:h, 0:w]
    target = np.rint(xs + sign * disp).astype(np.int64)
    ok = np.isfinite(disp) & (target >= 0) & (target < w)
    np.maximum.at(out, (ys[ok], target[ok]), disp[ok])
    out[~np.isfinite(out)] = np.nan
    return out


def fill_from_background(disp):
    """Each hole of a row takes the smaller of its two nearest known values."""
    out = disp.copy()
    w = out.shape[1]
    columns = np.arange(w)
    for row in out:
        holes = np.isnan(row)
        if holes.all():
            row[:] = 0
            continue
        left = np.maximum.accumulate(np.where(~holes, columns, -1))
        right = np.minimum.accumulate(np.where(~holes, columns, w)[::-1])[::-1]
        from_left = np.where(left >= 0, row[np.clip(left, 0, w - 1)], np.inf)
        from_right = np.where(right < w, row[np.clip(right, 0, w - 1)], np.inf)
        row[holes] = np.minimum(from_left, from_right)[holes]
    return out


def edge_band(warped_disp, jump, band):
    """Pixels within `band` px (a square) of a disparity jump of at least `jump` px."""
    d = fill_from_background(warped_disp)
    edges = np.zeros(d.shape, np.uint8)
    across = np.abs(np.diff(d, axis=1)) >= jump
    down = np.abs(np.diff(d, axis=0)) >= jump
    edges[:, :-1] |= across
    edges[:, 1:] |= across
    edges[:-1, :] |= down
    edges[1:, :] |= down
    if band > 0:
        edges = cv2.dilate(edges, np.ones((2 * band + 1, 2 * band + 1), np.uint8))
    return edges > 0


def border_strip(mask, source_disp, sign):
    """Region a: the columns outside the input's view, from the side the camera moved toward."""
    from_edge = mask if sign > 0 else mask[:, ::-1]
    leading = np.logical_and.accumulate(from_edge, axis=1)
    leading = leading if sign > 0 else leading[:, ::-1]
    columns = np.arange(mask.shape[1])[None, :]
    shifted = source_disp >= 0.5
    if sign > 0:
        first = np.where(shifted, np.floor(columns + source_disp), np.inf).min(axis=1)
        outside = columns < first[:, None]
    else:
        last = np.where(shifted, np.ceil(columns - source_disp), -np.inf).max(axis=1)
        outside = columns > last[:, None]
    return leading | outside


def regions(new, real, mask, source_disp, sign, jump, band):
    """Each region's share of the pixels and of the squared error, and the PSNR without its error."""
    error = ((new.astype(np.float64) - real) ** 2).sum(axis=2)
    a = border_strip(mask, source_disp, sign)
    visible = ~mask & ~a
    c = edge_band(forward_warp(source_disp, sign), jump, band) & visible
    masks = {"a": a, "b": mask & ~a, "c": c, "d": visible & ~c}
    total, values = error.sum(), error.size * 3
    scores = {"psnr": 10 * np.log10(255.0**2 * values / total)}
    for name, region in masks.items():
        rest = total - error[region].sum()
        scores[name] = {
            "pixels": float(region.mean()),
            "error": float(error[region].sum() / total),
            "psnr_if_perfect": float(10 * np.log10(255.0**2 * values / rest)) if rest > 0 else float("inf"),
        }
    return scores


def extrapolate(mbs_tool, left, right, out):
    """mbs-tool extrapolate with its defaults; the folder it wrote."""
    subprocess.run(
        [mbs_tool, "extrapolate", "--left", left, "--right", right, "--out", out],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    return out


def scene_views(mbs_tool, work, name, paths, step, jump, band):
    """The region scores of every new view of the scene `name` at one step."""
    scores = []
    for k in range(step, len(paths) - 2 * step):
        left, right = (os.path.join(TESTDATA, paths[i]) for i in (k, k + step))
        out = extrapolate(mbs_tool, left, right, os.path.join(work, f"{name}_{step}_{k}"))
        for image, disparity, sign, target in (("1", "2", 1, k - step), ("4", "3", -1, k + 2 * step)):
            new = read_rgb(os.path.join(out, f"image_{image}.png"))
            mask = cv2.imread(os.path.join(out, f"mask_{image}.png"), cv2.IMREAD_GRAYSCALE) > 0
            source_disp = read_pfm(os.path.join(out, f"disparity_{disparity}.pfm")).astype(np.float64)
            real = read_rgb(os.path.join(TESTDATA, paths[target]))
            scores.append(regions(new, real, mask, source_disp, sign, jump, band))
    return scores


def table(scores_by_scene):
    """Markdown rows: per scene and the mean over views, each region as pixels % / error % / gain."""
    rows = []
    every = [s for scores in scores_by_scene.values() for s in scores]
    for name, scores in [*scores_by_scene.items(), (f"mean ({len(every)} views)", every)]:
        base = np.mean([s["psnr"] for s in scores])
        cells = []
        for r in REGIONS:
            pixels = 100 * np.mean([s[r]["pixels"] for s in scores])
            error = 100 * np.mean([s[r]["error"] for s in scores])
            gain = np.mean([s[r]["psnr_if_perfect"] for s in scores]) - base
            cells.append(f"{pixels:.1f} / {error:.1f} / +{gain:.2f}")
        rows.append(f"| {name} | {len(scores)} | {base:.2f} | " + " | ".join(cells) + " |")
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mbs-tool", default="target/release/mbs-tool")
    parser.add_argument("--edge-jump", type=float, default=2.0, help="disparity jump of a depth edge, px")
    parser.add_argument("--edge-band", type=int, default=2, help="half width of the band around an edge, px")
    parser.add_argument("--json", help="also write every view's scores here")
    args = parser.parse_args()
    results = {}
    with tempfile.TemporaryDirectory() as work:
        for step in (1, 2):
            results[step] = {
                name: scene_views(args.mbs_tool, work, name, paths, step, args.edge_jump, args.edge_band)
                for name, paths, _ in SCENES
            }
            results[step] = {name: scores for name, scores in results[step].items() if scores}
    for step, by_scene in results.items():
        print(f"\n{'Adjacent pairs' if step == 1 else 'Pairs two views apart'}: each region's pixels % / "
              "error % / PSNR gain (dB) if it were perfect")
        print("| scene | views | PSNR | a: border strip | b: disoccluded | c: depth edges | d: other visible |")
        print("| --- | ---: | ---: | --- | --- | --- | --- |")
        print("\n".join(table(by_scene)))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({str(step): by_scene for step, by_scene in results.items()}, f, indent=1)


if __name__ == "__main__":
    main()
