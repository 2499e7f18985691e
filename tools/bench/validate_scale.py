#!/usr/bin/env python3
"""`mbs-tool validate` at MBS20K scale against the Python check a user would write.

Builds an MBS20K-sized tree (7 towns x 5 weathers, 20,417 frames, 5 views
+ depth each: 122,502 files) by hard-linking a few rendered 960x540 frames,
scans it into a manifest, then times:
  - mbs fast mode (headers + PNG trailers, parallel) vs a Python peer that
    opens every file's header with Pillow (lazy open) and checks sizes/modes;
  - mbs --deep (full decode) vs a peer that decodes with cv2.imread, on a
    subset of --deep-samples samples.

Usage (repo root; needs numpy, opencv-python-headless and pillow):
    python3 tools/bench/validate_scale.py [--samples 20417] [--deep-samples 300]
"""

import argparse
import json
import os
import shutil
import subprocess
import tempfile
import time

import cv2
from PIL import Image

TOWNS = ["Town01", "Town02", "Town03", "Town05", "Town06", "Town07", "Town10"]
WEATHERS = ["ClearNight", "ClearNoon", "ClearSunset", "CloudyNoon", "MidRainyNoon"]
FILES = ["rgb_%d.png" % k for k in range(5)] + ["depth_0.png"]


def peer_fast(manifest_path):
    root = os.path.dirname(manifest_path)
    manifest = json.load(open(manifest_path))
    w, h = manifest["rig"]["width"], manifest["rig"]["height"]
    problems, seen = 0, set()
    for s in manifest["samples"]:
        problems += s["id"] in seen
        seen.add(s["id"])
        problems += len(s["views"]) != manifest["rig"]["num_views"]
        for rel in s["views"] + [s["depth"]]:
            path = os.path.join(root, rel)
            if not os.path.isfile(path):
                problems += 1
                continue
            with Image.open(path) as im:
                problems += im.size != (w, h) or (rel.endswith("depth_0.png") and im.mode != "RGB")
    return problems


def peer_deep(manifest_path, limit):
    root = os.path.dirname(manifest_path)
    manifest = json.load(open(manifest_path))
    w, h = manifest["rig"]["width"], manifest["rig"]["height"]
    problems = 0
    for s in manifest["samples"][:limit]:
        for rel in s["views"] + [s["depth"]]:
            im = cv2.imread(os.path.join(root, rel), cv2.IMREAD_UNCHANGED)
            problems += im is None or im.shape[:2] != (h, w)
    return problems


def timed(cmd):
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=20417)
    parser.add_argument("--deep-samples", type=int, default=300)
    args = parser.parse_args()

    subprocess.run(["cargo", "build", "--release", "-q", "-p", "mbs-tool"], check=True)
    tool = os.path.join("target", "release", "mbs-tool")
    work = tempfile.mkdtemp(prefix="mbs-validate-bench-")
    try:
        src = os.path.join(work, "src")
        subprocess.run([tool, "synth", "--out", src, "--frames", "4", "--towns", "Town01", "--weathers", "ClearNoon",
                        "--no-checksums"], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        scenes = sorted(os.path.join(src, "Town01", "ClearNoon", d) for d in os.listdir(os.path.join(src, "Town01", "ClearNoon")))
        root = os.path.join(work, "MBS20K")
        for i in range(args.samples):
            town, weather = TOWNS[i % len(TOWNS)], WEATHERS[(i // len(TOWNS)) % len(WEATHERS)]
            frame = os.path.join(root, town, weather, "%06d" % i)
            os.makedirs(frame)
            scene = scenes[i % len(scenes)]
            for f in FILES:
                os.link(os.path.join(scene, f), os.path.join(frame, f))
        manifest = os.path.join(root, "manifest.json")
        scan = timed([tool, "scan", root])
        # Warm the cache the same way for both sides.
        peer_fast(manifest)
        fast = min(timed([tool, "validate", manifest]) for _ in range(2))
        start = time.perf_counter()
        assert peer_fast(manifest) == 0
        peer = time.perf_counter() - start

        sub = dict(json.load(open(manifest)))
        sub["samples"] = sub["samples"][: args.deep_samples]
        sub_path = os.path.join(root, "subset.json")
        json.dump(sub, open(sub_path, "w"))
        deep = timed([tool, "validate", sub_path, "--deep"])
        start = time.perf_counter()
        assert peer_deep(sub_path, args.deep_samples) == 0
        peer_d = time.perf_counter() - start

        n, files = args.samples, args.samples * len(FILES)
        print("validate: %d samples, %d files (960x540 PNGs, page cache warm), %d cores" % (n, files, os.cpu_count()))
        print("| check | mbs (s) | peer (s) | files/s mbs | files/s peer | speed-up |")
        print("|---|---:|---:|---:|---:|---:|")
        print("| scan (MBS20K tree -> manifest) | %.2f | | | | |" % scan)
        print("| fast: headers + trailers vs Pillow lazy open | %.2f | %.2f | %.0f | %.0f | %.2fx |"
              % (fast, peer, files / fast, files / peer, peer / fast))
        k = args.deep_samples * len(FILES)
        print("| deep (%d samples): full decode vs cv2.imread | %.2f | %.2f | %.0f | %.0f | %.2fx |"
              % (args.deep_samples, deep, peer_d, k / deep, k / peer_d, peer_d / deep))
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
