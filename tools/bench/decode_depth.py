#!/usr/bin/env python3
"""decode-depth against the Python peer a user would write, in one run.

The peer: cv2.imread + numpy CARLA decode + PFM write, one process (what the
authors' loader does per file). mbs: `mbs-tool decode-depth` (all cores).
Both decode the same 540x960 CARLA depth PNGs rendered by `mbs-tool synth`
and the outputs are compared for equality.

Usage (from the repo root; needs numpy and opencv-python-headless):
    python3 tools/bench/decode_depth.py [--frames 200] [--scenes 8]
"""

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

MAX_DEPTH = 200.0


def peer_decode(png_path, pfm_path):
    bgr = cv2.imread(png_path, cv2.IMREAD_UNCHANGED)
    b, g, r = (bgr[..., i].astype(np.float64) for i in range(3))
    depth = (1000.0 * (r + 256.0 * g + 65536.0 * b) / (256.0**3 - 1.0)).astype(np.float32)
    depth[depth > MAX_DEPTH] = np.inf
    with open(pfm_path, "wb") as f:
        f.write(b"Pf\n%d %d\n-1.0\n" % (depth.shape[1], depth.shape[0]))
        np.flipud(depth).astype("<f4").tofile(f)


def read_pfm(path):
    with open(path, "rb") as f:
        assert f.readline().strip() == b"Pf"
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.fromfile(f, dtype="<f4" if scale < 0 else ">f4", count=w * h)
    return np.flipud(data.reshape(h, w))


def timed(cmd):
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=200, help="depth PNGs to decode")
    parser.add_argument("--scenes", type=int, default=8, help="distinct rendered scenes, repeated to --frames")
    args = parser.parse_args()

    subprocess.run(["cargo", "build", "--release", "-q", "-p", "mbs-tool"], check=True)
    tool = os.path.join("target", "release", "mbs-tool")
    work = tempfile.mkdtemp(prefix="mbs-bench-")
    try:
        src = os.path.join(work, "src")
        subprocess.run(
            [tool, "synth", "--out", src, "--frames", str(args.scenes), "--towns", "Town01",
             "--weathers", "ClearNoon"],
            check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        scenes = sorted(
            os.path.join(d, "depth_0.png") for d, _, files in os.walk(src) if "depth_0.png" in files)
        data = os.path.join(work, "data")
        pngs = []
        for i in range(args.frames):
            frame = os.path.join(data, "Town01", "ClearNoon", "%06d" % i)
            os.makedirs(frame)
            shutil.copy(scenes[i % len(scenes)], os.path.join(frame, "depth_0.png"))
            pngs.append(os.path.join(frame, "depth_0.png"))
        mb = sum(os.path.getsize(p) for p in pngs) / 1e6

        # Warm the page cache so both sides read from memory.
        for p in pngs:
            with open(p, "rb") as f:
                f.read()

        start = time.perf_counter()
        for p in pngs:
            cv2.imread(p, cv2.IMREAD_UNCHANGED)
        read_only = time.perf_counter() - start

        peer_out = os.path.join(work, "peer")
        start = time.perf_counter()
        for i, p in enumerate(pngs):
            out = os.path.join(peer_out, "%06d" % i)
            os.makedirs(out)
            peer_decode(p, os.path.join(out, "depth_0.pfm"))
        peer = time.perf_counter() - start

        mbs_pfm = timed([tool, "decode-depth", data, "--out", os.path.join(work, "pfm"), "--depth-format", "pfm"])
        mbs_exr = timed([tool, "decode-depth", data, "--out", os.path.join(work, "exr")])
        mbs_pairs = timed([tool, "decode-depth", data, "--out", os.path.join(work, "pairs"), "--all-pairs"])

        worst = 0.0
        for i in range(0, args.frames, max(1, args.frames // 10)):
            a = read_pfm(os.path.join(peer_out, "%06d" % i, "depth_0.pfm"))
            b = read_pfm(os.path.join(work, "pfm", "Town01", "ClearNoon", "%06d" % i, "depth_0.pfm"))
            same_inf = np.array_equal(np.isinf(a), np.isinf(b))
            finite = np.isfinite(a)
            worst = max(worst, float(np.max(np.abs(a[finite] - b[finite]))) if finite.any() else 0.0)
            if not same_inf:
                sys.exit("invalid pixels differ between mbs and the peer on frame %d" % i)

        n = args.frames
        print("decode-depth: %d CARLA depth PNGs, 960x540, %.1f MB, %d cores" % (n, mb, os.cpu_count()))
        print("| pipeline | time (s) | images/s | vs peer |")
        print("|---|---:|---:|---:|")
        print("| cv2.imread only (peer's read) | %.2f | %.1f | |" % (read_only, n / read_only))
        print("| peer: cv2.imread + numpy decode + PFM write | %.2f | %.1f | 1.00x |" % (peer, n / peer))
        for name, t in [("mbs decode-depth --depth-format pfm", mbs_pfm), ("mbs decode-depth (EXR)", mbs_exr),
                        ("mbs decode-depth --all-pairs (EXR + 4 KITTI PNGs)", mbs_pairs)]:
            print("| %s | %.2f | %.1f | %.2fx |" % (name, t, n / t, peer / t))
        print("max |mbs - peer| over finite depth: %.3g m (outputs agree)" % worst)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
