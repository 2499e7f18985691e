#!/usr/bin/env python3
"""Built-in SGM (mbs-infer) against OpenCV StereoSGBM, in the same run.

OpenCV: MODE_SGBM_3WAY, blockSize 5, P1 = 8*3*5^2, P2 = 32*3*5^2,
disp12MaxDiff 1, uniquenessRatio 10, speckle 100 / 2, cv2.setNumThreads(2).
SGM: the release example `sgm_bench` (default settings) with
RAYON_NUM_THREADS=2. Both run in alternating rounds on the same machine
(each SGM process warms up once); the fastest run of each counts, the
estimate least disturbed by other load on a shared machine. CPU time per
pair (all threads, user + system; for SGM the difference between a run of
2N and one of N pairs) is reported too: it measures the work done and is
far less sensitive to other load than wall time.

Pairs: Middlebury Teddy (450x375; 64 disparities, and 16 for timing only)
and a KITTI-size pair (1242x375, 128 disparities) tiled from Teddy (views
and GT tiled alike; the seams cost both matchers the same).

Accuracy over all valid GT pixels: OpenCV leaves invalid pixels, which
count as errors in Out-2 ("raw"); "filled" applies the same
background-side row fill that SGM uses, for a like-for-like comparison.

Needs numpy and opencv-python-headless (not part of CI). Run from the
repository root:  python3 tools/bench/sgm_vs_opencv.py
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data" / "middlebury-teddy"


def fill_background(d):
    """Row-wise fill of non-finite pixels with the smaller nearest valid value."""
    out = d.copy()
    h, w = d.shape
    idx = np.arange(w)
    for y in range(h):
        row = out[y]
        ok = np.isfinite(row)
        if not ok.any():
            continue
        li = np.maximum.accumulate(np.where(ok, idx, -1))
        ri = np.minimum.accumulate(np.where(ok, idx, w)[::-1])[::-1]
        lv = np.where(li >= 0, row[np.clip(li, 0, w - 1)], np.inf)
        rv = np.where(ri < w, row[np.clip(ri, 0, w - 1)], np.inf)
        row[~ok] = np.minimum(lv, rv)[~ok]
    return out


def scores(d, gt):
    valid = np.isfinite(gt)
    with np.errstate(invalid="ignore"):
        err = np.abs(d - gt)[valid]
    fin = np.isfinite(err)
    return {
        "epe": float(err[fin].mean()),
        "out2": float(100 * np.mean(~(err <= 2))),
        "density": float(100 * fin.mean()),
    }


def make_sgbm(ndisp):
    bs = 5
    return cv2.StereoSGBM_create(
        minDisparity=0, numDisparities=ndisp, blockSize=bs,
        P1=8 * 3 * bs * bs, P2=32 * 3 * bs * bs, disp12MaxDiff=1,
        uniquenessRatio=10, speckleWindowSize=100, speckleRange=2,
        mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)


def timed(sgbm, left, right, repeats):
    """`repeats` calls of `sgbm` on the pair: each call's wall time (ms) and the last disparity."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        d = sgbm.compute(left, right)
        times.append(1e3 * (time.perf_counter() - t))
    return times, d


def opencv(left, right, ndisp, repeats):
    sgbm = make_sgbm(ndisp)
    cpu = time.process_time()
    times, d = timed(sgbm, left, right, repeats)
    cpu_ms = 1e3 * (time.process_time() - cpu) / repeats
    d = d.astype(np.float32) / 16
    d[d < 0] = np.inf
    return min(times), cpu_ms, d


def sgm(binary, left, right, ndisp, repeats, gt_path, gt_scale):
    """Runs sgm_bench twice (repeats and 2 x repeats): its JSON from the
    longer run and the CPU time per pair from the difference of the two."""
    results = []
    for n in (repeats, 2 * repeats):
        cmd = [str(binary), str(left), str(right), str(ndisp), str(n), "5"]
        if gt_path is not None:
            cmd += [str(gt_path), str(gt_scale)]
        env = dict(os.environ, RAYON_NUM_THREADS="2")
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        out = subprocess.run(cmd, check=True, capture_output=True, text=True, env=env)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
        results.append((json.loads(out.stdout), cpu))
    res = results[1][0]
    res["cpu_ms"] = 1e3 * (results[1][1] - results[0][1]) / repeats
    return res


def medians(binary, cases, rounds):
    """Median wall time per pair of each matcher over alternating rounds, 1 and 2 threads."""
    print("| pair | disp | threads | OpenCV median ms | SGM median ms | SGM / OpenCV |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for threads in (1, 2):
        cv2.setNumThreads(threads)
        env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
        for name, lp, rp, l, r, nd, _, _ in cases:
            sgbm, cv_ms, sgm_ms = make_sgbm(nd), [], []
            sgbm.compute(l, r)
            for _ in range(rounds):
                cv_ms += timed(sgbm, l, r, 3)[0]
                out = subprocess.run([str(binary), str(lp), str(rp), str(nd), "3", "5"], check=True,
                                     capture_output=True, text=True, env=env)
                sgm_ms.append(json.loads(out.stdout)["time_ms"])
            cv_med, sgm_med = float(np.median(cv_ms)), float(np.median(sgm_ms))
            print(f"| {name} | {nd} | {threads} | {cv_med:.1f} | {sgm_med:.1f} | {sgm_med / cv_med:.2f}x |")
            sys.stdout.flush()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=10, help="runs per round")
    ap.add_argument("--rounds", type=int, default=5,
                    help="alternating rounds of OpenCV and SGM runs; the fastest run counts")
    ap.add_argument("--no-build", action="store_true", help="use the built binary")
    ap.add_argument("--medians", type=int, default=0, metavar="ROUNDS",
                    help="instead: median times over ROUNDS alternating rounds (3 OpenCV calls, then one "
                         "SGM process of 3 pairs) on 1 and then 2 threads; steadier than the fastest run "
                         "on a shared machine")
    ap.add_argument("--native", action="store_true",
                    help="build SGM with RUSTFLAGS='-C target-cpu=native' (in target/native); the "
                         "default build already runs the matcher's loops on AVX2 where the processor "
                         "has it, chosen at run time as OpenCV chooses its kernels")
    args = ap.parse_args()
    cv2.setNumThreads(2)
    target = ROOT / "target" / ("native" if args.native else "")
    if not args.no_build:
        env = dict(os.environ)
        if args.native:
            env.update(CARGO_TARGET_DIR=str(target), RUSTFLAGS="-C target-cpu=native")
        subprocess.run(["cargo", "build", "--release", "-q", "-p", "mbs-infer",
                        "--example", "sgm_bench"], check=True, cwd=ROOT, env=env)
    binary = target / "release" / "examples" / "sgm_bench"

    tmp = Path(tempfile.mkdtemp(prefix="sgm_bench_"))
    left, right = cv2.imread(str(DATA / "im2.png")), cv2.imread(str(DATA / "im6.png"))
    codes = cv2.imread(str(DATA / "disp2.png"), cv2.IMREAD_GRAYSCALE)
    gt = np.where(codes == 0, np.inf, codes.astype(np.float32) / 4)
    # KITTI-size pair: Teddy tiled three times across, cropped to 1242 px.
    tile = lambda a: np.concatenate([a, a, a], axis=1)[:, :1242]
    kl, kr, kcodes = tile(left), tile(right), tile(codes)
    cv2.imwrite(str(tmp / "kl.png"), kl)
    cv2.imwrite(str(tmp / "kr.png"), kr)
    cv2.imwrite(str(tmp / "kgt.png"), kcodes)
    kgt = np.where(kcodes == 0, np.inf, kcodes.astype(np.float32) / 4)

    cases = [
        ("Teddy 450x375", DATA / "im2.png", DATA / "im6.png", left, right, 64, DATA / "disp2.png", gt),
        ("Teddy 450x375", DATA / "im2.png", DATA / "im6.png", left, right, 16, None, None),
        ("KITTI-size 1242x375 (tiled Teddy)", tmp / "kl.png", tmp / "kr.png", kl, kr, 128, tmp / "kgt.png", kgt),
    ]
    if args.medians:
        medians(binary, cases, args.medians)
        return
    print("| pair | disp | OpenCV ms | SGM ms | SGM / OpenCV | OpenCV CPU ms | SGM CPU ms | CPU ratio "
          "| OpenCV EPE / Out-2 raw (density) | OpenCV EPE / Out-2 filled | SGM EPE / Out-2 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, lp, rp, l, r, nd, gp, g in cases:
        cv_ms, sgm_ms, cv_cpu, sgm_cpu = (float("inf"),) * 4
        for _ in range(args.rounds):
            t, c, d = opencv(l, r, nd, args.repeats)
            res = sgm(binary, lp, rp, nd, args.repeats, gp, 4)
            cv_ms, sgm_ms = min(cv_ms, t), min(sgm_ms, res["min_ms"])
            cv_cpu, sgm_cpu = min(cv_cpu, c), min(sgm_cpu, res["cpu_ms"])
        acc = ["n/a (timing only)"] * 3
        if g is not None:
            raw, filled = scores(d, g), scores(fill_background(d), g)
            acc = [
                f"{raw['epe']:.2f} / {raw['out2']:.1f} % ({raw['density']:.0f} %)",
                f"{filled['epe']:.2f} / {filled['out2']:.1f} %",
                f"{res['epe']:.2f} / {res['out2']:.1f} %",
            ]
        print(f"| {name} | {nd} | {cv_ms:.1f} | {sgm_ms:.1f} | {sgm_ms / cv_ms:.2f}x | "
              f"{cv_cpu:.1f} | {sgm_cpu:.1f} | {sgm_cpu / cv_cpu:.2f}x | " + " | ".join(acc) + " |")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
