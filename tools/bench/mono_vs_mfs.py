#!/usr/bin/env python3
"""Images per second of `mbs-tool mono` against an MfS-style numpy/OpenCV pipeline, in one run.

The same depth model (FastDepth) for both, the peer's through Python's
onnxruntime.

The photos: the 28 real Middlebury views of testdata/ at their sizes (Teddy
im2/im6 450x375, Tsukuba col1-5 384x288, Baby2 view0-6 413x370, Bowling2
view0-6 443x370, Laundry view0-6 447x370), copied into one folder.

mbs: the whole command, `mbs-tool mono --images DIR --model fastdepth_7.onnx
--card fastdepth --out OUT` (defaults: 4 cameras, the photo at camera 1,
--jobs one per core), timed from process start to exit: reading the photos,
FastDepth through ONNX Runtime (224x224, resized back), the range scaling,
three synthesised views (warp, mask, background fill), writing image_K and
mask_K PNGs, disparity_2 PFMs, the linked photo and manifest.json.

Peer, what Watson et al.'s stereo-from-mono (MfS) does per image, in numpy,
OpenCV, scikit-image and scipy, one process, run by the venv's Python:
- depth: cv2.imread, BGR to RGB, cv2.resize to 224x224 (INTER_LINEAR), /255,
  `InferenceSession.run` (CPU, default threads), cv2.resize back
  (INTER_LINEAR), inverse depth;
- MfS's process_disparity: shifted to start at 0 if negative, divided by its
  largest value, times a scale drawn per image (as mbs: 0.05-0.15 of the
  width), then MfS's sharpening, on by default there: pixels where
  skimage's sobel of the disparity exceeds 3 are dropped and refilled from
  the nearest kept pixel by scipy's griddata (mbs does no sharpening);
- warp, for each of the three views (-1, +1, +2 baselines): MfS's
  project_image in vectorised numpy (its own code loops over columns): each
  pixel lands on the floor and ceiling of x -+ k d; a pixel is occluded
  when a pixel over 1 px nearer lands on both its targets (a z-buffer
  standing for MfS's get_occlusion_mask, which asks whether a pixel 2 or
  more columns further lands there); each target keeps the nearest pixel
  (in position) of each of the two taps, and the two are blended with
  inverse-distance weights;
- fill: the pixels nothing landed on are filled with cv2.inpaint TELEA
  (radius 3), where MfS pastes a colour-matched other image (its
  "background"), and a 255 mask of them is kept;
- writes: cv2.imwrite of the three views and masks, the disparity as PFM,
  the photo hard-linked and a JSON list of the files: mbs's outputs.

mbs does less work on the disparity (no sharpening) and more in the fill
(a background-side fill, not a pasted image); the peer's per-stage seconds
are printed so either difference can be taken out.

Alternating runs, a warm-up of each first; each side gets a fresh output
folder every run; the median of --rounds runs counts (the best is shown).
The peer's time runs from creating its InferenceSession to its last write
(interpreter start and imports excluded, its whole process shown beside).

Needs a release mbs-tool, ONNX Runtime for it (ORT_DYLIB_PATH or the
project's .ort/, tools/setup-ort.sh), the FastDepth file
(tools/setup-depth-model.sh) and a venv with the peer's packages (not part
of CI). From the repository root:

    cargo build --release -p mbs-tool
    python3 -m venv .venv-bench
    .venv-bench/bin/pip install numpy opencv-python-headless onnxruntime==1.31.1 scipy scikit-image
    python3 tools/bench/mono_vs_mfs.py [--rounds 3] [--venv .venv-bench]
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TESTDATA = ROOT / "testdata"

# (id prefix, folder, file names): every real Middlebury view in testdata/.
PHOTOS = [
    ("teddy", "middlebury-teddy", ["im2.png", "im6.png"]),
    ("tsukuba", "middlebury-tsukuba-row3", [f"scene1.row3.col{k}.ppm" for k in range(1, 6)]),
    ("baby2", "middlebury-baby2", [f"view{k}.png" for k in range(7)]),
    ("bowling2", "middlebury-bowling2", [f"view{k}.png" for k in range(7)]),
    ("laundry", "middlebury-laundry", [f"view{k}.png" for k in range(7)]),
]

# The paper's sets, mbs's default: cameras 0..3, the photo at camera 1.
VIEWS, REFERENCE = 4, 1
FASTDEPTH_SIZE = 224
SCALE_RANGE = (0.05, 0.15)
STAGES = ["read", "depth", "scale", "sharpen", "warp", "inpaint", "write"]


def prepare_photos(folder):
    """Copies the testdata views into `folder` as ID.EXT; returns their sizes."""
    folder.mkdir(parents=True)
    sizes = {}
    for prefix, directory, names in PHOTOS:
        for name in names:
            source = TESTDATA / directory / name
            stem = name.split(".")[-2]
            target = folder / f"{prefix}-{stem}{source.suffix}"
            shutil.copyfile(source, target)
            sizes[target.name] = image_size(target)
    return sizes


def image_size(path):
    """Width and height from a PNG or binary PPM header."""
    data = path.read_bytes()[:64]
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    width, height = data.split(b"\n")[1].split()
    return int(width), int(height)


def run_mbs(binary, model, photos, out):
    """Seconds of one whole `mbs-tool mono` run."""
    command = [str(binary), "mono", "--images", str(photos), "--model", str(model), "--card", "fastdepth",
               "--out", str(out)]
    start = time.perf_counter()
    done = subprocess.run(command, check=False, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"mbs-tool mono failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return seconds


def run_peer(python, model, photos, out):
    """The peer's seconds (session to last write), its whole process's, and its stages."""
    command = [str(python), __file__, "--peer", str(photos), str(out), "--model", str(model)]
    start = time.perf_counter()
    done = subprocess.run(command, check=False, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"the Python peer failed ({done.returncode}):\n{done.stderr[-2000:]}")
    report = json.loads(done.stdout.strip().splitlines()[-1])
    return report["seconds"], wall, report


# --- The peer: runs in the venv's Python (`--peer PHOTOS OUT`). -------------


def write_pfm(path, values):
    """A one-channel little-endian PFM, rows bottom to top."""
    import numpy as np

    height, width = values.shape
    with open(path, "wb") as f:
        f.write(f"Pf\n{width} {height}\n-1.0\n".encode())
        f.write(np.ascontiguousarray(values[::-1], dtype="<f4").tobytes())


def process_disparity(inverse, rng, sharpen=True):
    """MfS's process_disparity: shift, normalise, scale by a drawn fraction of the width, sharpen.

    Returns the disparity and the seconds spent sharpening.
    """
    import numpy as np
    from scipy.interpolate import griddata
    from skimage.filters import sobel

    disparity = inverse.astype(np.float64)
    least = disparity.min()
    if least < 0:
        disparity += abs(least)
    disparity /= disparity.max()
    height, width = disparity.shape
    disparity *= (SCALE_RANGE[0] + rng.random() * (SCALE_RANGE[1] - SCALE_RANGE[0])) * width
    start = time.perf_counter()
    if sharpen:
        # Disparity edges are set to the nearest kept value: no flying pixels.
        disparity[sobel(disparity) > 3] = 0
        keep = disparity > 0
        ys, xs = np.mgrid[0:height, 0:width]
        try:
            disparity = griddata(np.stack([ys[keep], xs[keep]], 1), disparity[keep],
                                 np.stack([ys.ravel(), xs.ravel()], 1), method="nearest").reshape(height, width)
        except (ValueError, IndexError):
            pass
    return disparity.astype(np.float32), time.perf_counter() - start


def nearest_per_target(targets, distance, count):
    """For each target index, the position in `targets` of its entry of least distance (-1: none)."""
    import numpy as np

    best = np.full(count, -1, np.int64)
    if targets.size:
        order = np.lexsort((distance, targets))
        first = np.ones(order.size, bool)
        first[1:] = targets[order[1:]] != targets[order[:-1]]
        best[targets[order[first]]] = order[first]
    return best


def project(image, disparity, sign, same_surface=1.0):
    """MfS's project_image, vectorised: a forward warp x -> x + sign * d to the floor and ceiling.

    A pixel is dropped when a pixel over `same_surface` nearer lands on both
    its targets; each target takes the nearest (in position) pixel per tap,
    and the two taps are blended by inverse distance. Returns the view
    (holes black) and the 255 mask of the pixels nothing landed on.
    """
    import numpy as np

    height, width = disparity.shape
    location = np.arange(width, dtype=np.float32)[None, :] + sign * disparity
    up, down = np.ceil(location).astype(np.int64), np.floor(location).astype(np.int64)
    weight_up = up - location  # distance to the ceiling
    weight_down = 1 - weight_up  # MfS's weight of the floor
    rows = np.arange(height)[:, None] * width
    # The z-buffer: the nearest disparity landing on each target, by either tap.
    zbuffer = np.full(height * width, -np.inf, np.float32)
    taps = []
    for column in (up, down):
        inside = (column >= 0) & (column < width)
        target = np.where(inside, rows + column, 0)
        np.maximum.at(zbuffer, target[inside], disparity[inside])
        taps.append((inside, target))
    visible = np.zeros((height, width), bool)
    for inside, target in taps:
        visible |= inside & (disparity >= zbuffer[target] - same_surface)
    flat = image.reshape(-1, 3).astype(np.float32)
    colours, weights = [], []
    for (inside, target), distance in zip(taps, (weight_up, weight_down)):
        use = (inside & visible).ravel()
        source = np.flatnonzero(use)
        best = nearest_per_target(target.ravel()[use], distance.ravel()[use], height * width)
        landed = best >= 0
        colour = np.zeros((height * width, 3), np.float32)
        colour[landed] = flat[source[best[landed]]]
        weight = np.full(height * width, 10000.0, np.float32)
        weight[landed] = distance.ravel()[source[best[landed]]]
        colours.append(colour)
        weights.append(weight)
    total = weights[0] + weights[1] + 1e-7
    blended = colours[0] * (weights[1] / total)[:, None] + colours[1] * (weights[0] / total)[:, None]
    holes = (weights[0] == 10000.0) & (weights[1] == 10000.0)
    view = np.clip(np.rint(blended), 0, 255).astype(np.uint8).reshape(height, width, 3)
    return view, (holes * 255).astype(np.uint8).reshape(height, width)


def peer(photos, out, model):
    """The MfS-style pipeline over every photo of `photos`; prints its seconds and stages as JSON."""
    import cv2
    import numpy as np
    import onnxruntime
    import scipy.interpolate
    import skimage.filters

    # The helpers' imports, loaded before the clock starts (skimage loads lazily).
    assert callable(scipy.interpolate.griddata) and callable(skimage.filters.sobel)

    stages = dict.fromkeys(STAGES, 0.0)
    start = time.perf_counter()
    options = onnxruntime.SessionOptions()
    options.log_severity_level = 3  # the model's unused initialisers warn otherwise
    session = onnxruntime.InferenceSession(str(model), options, providers=["CPUExecutionProvider"])
    input_name = session.get_inputs()[0].name
    load = time.perf_counter() - start
    folders = {k: out / f"image_{k + 1}" for k in range(VIEWS)}
    masks = {k: out / f"mask_{k + 1}" for k in range(VIEWS) if k != REFERENCE}
    disparities = out / f"disparity_{REFERENCE + 1}"
    for folder in [*folders.values(), *masks.values(), disparities]:
        folder.mkdir(parents=True)
    written = []
    for index, path in enumerate(sorted(photos.iterdir())):
        photo_id = path.stem
        clock = time.perf_counter()
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
        now = time.perf_counter()
        stages["read"] += now - clock
        clock = now
        height, width = bgr.shape[:2]
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        small = cv2.resize(rgb, (FASTDEPTH_SIZE, FASTDEPTH_SIZE), interpolation=cv2.INTER_LINEAR)
        tensor = (small.astype(np.float32) / 255).transpose(2, 0, 1)[None]
        depth = session.run(None, {input_name: tensor})[0][0, 0]
        depth = cv2.resize(depth, (width, height), interpolation=cv2.INTER_LINEAR)
        now = time.perf_counter()
        stages["depth"] += now - clock
        clock = now
        disparity, sharpening = process_disparity(1 / depth, np.random.default_rng(index))
        now = time.perf_counter()
        stages["sharpen"] += sharpening
        stages["scale"] += now - clock - sharpening
        views = {}
        for k in range(VIEWS):
            if k == REFERENCE:
                continue
            # Cameras left of the photo see it shifted right (x + d), right of it left (x - d).
            sign = 1.0 if k < REFERENCE else -1.0
            clock = time.perf_counter()
            warped, holes = project(bgr, disparity * abs(k - REFERENCE), sign)
            now = time.perf_counter()
            stages["warp"] += now - clock
            views[k] = (cv2.inpaint(warped, holes, 3, cv2.INPAINT_TELEA), holes)
            stages["inpaint"] += time.perf_counter() - now
        clock = time.perf_counter()
        for k, (view, holes) in views.items():
            cv2.imwrite(str(folders[k] / f"{photo_id}.png"), view)
            cv2.imwrite(str(masks[k] / f"{photo_id}.png"), holes)
        write_pfm(disparities / f"{photo_id}.pfm", disparity)
        linked = folders[REFERENCE] / path.name
        try:
            os.link(path, linked)
        except OSError:
            shutil.copyfile(path, linked)
        written.append(photo_id)
        stages["write"] += time.perf_counter() - clock
    clock = time.perf_counter()
    (out / "samples.json").write_text(json.dumps({"views": VIEWS, "reference": REFERENCE, "samples": written}))
    stages["write"] += time.perf_counter() - clock
    seconds = time.perf_counter() - start
    print(json.dumps({"seconds": seconds, "load": load, "stages": stages, "images": len(written),
                      "onnxruntime": onnxruntime.__version__, "numpy": np.__version__, "cv2": cv2.__version__}))


# --- The driver. --------------------------------------------------------------


def main():
    """Runs both pipelines in alternating rounds and prints their rates."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=3, help="timed runs of each, alternating; the median counts")
    parser.add_argument("--mbs-tool", default=str(ROOT / "target" / "release" / "mbs-tool"))
    parser.add_argument("--model", default=str(ROOT / ".models" / "fastdepth_7.onnx"))
    parser.add_argument("--venv", default=str(ROOT / ".venv-bench"),
                        help="the peer's venv (numpy, opencv-python-headless, onnxruntime, scipy, scikit-image); "
                        "this Python when it does not exist")
    parser.add_argument("--peer", nargs=2, metavar=("PHOTOS", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.peer:
        peer(Path(args.peer[0]), Path(args.peer[1]), Path(args.model))
        return 0
    python = Path(args.venv) / "bin" / "python"
    if not python.exists():
        python = Path(sys.executable)
    for path in (args.mbs_tool, args.model):
        if not Path(path).exists():
            sys.exit(f"{path} not found: see this script's docstring")

    with tempfile.TemporaryDirectory(prefix="mono_vs_mfs_") as tmp:
        tmp = Path(tmp)
        photos = tmp / "photos"
        sizes = prepare_photos(photos)
        images = len(sizes)
        by_size = {}
        for size in sizes.values():
            by_size[size] = by_size.get(size, 0) + 1
        print(f"{images} photos: " + ", ".join(f"{n} of {w}x{h}" for (w, h), n in by_size.items()), flush=True)

        run_mbs(args.mbs_tool, args.model, photos, tmp / "mbs-warm")
        _, _, report = run_peer(python, args.model, photos, tmp / "peer-warm")
        print(f"warm-up done; peer: onnxruntime {report['onnxruntime']}, numpy {report['numpy']}, "
              f"OpenCV {report['cv2']}", flush=True)
        mbs_times, peer_times, peer_walls, peer_stages = [], [], [], []
        for round_ in range(args.rounds):
            mbs_times.append(run_mbs(args.mbs_tool, args.model, photos, tmp / f"mbs{round_}"))
            seconds, wall, report = run_peer(python, args.model, photos, tmp / f"peer{round_}")
            peer_times.append(seconds)
            peer_walls.append(wall)
            peer_stages.append(report)
            print(f"round {round_ + 1}: mbs {mbs_times[-1]:.2f} s, MfS-style Python {seconds:.2f} s "
                  f"(process {wall:.2f} s) for {images} images", flush=True)
            shutil.rmtree(tmp / f"mbs{round_}")
            shutil.rmtree(tmp / f"peer{round_}")

    mbs_s, peer_s = statistics.median(mbs_times), statistics.median(peer_times)
    peer_wall = statistics.median(peer_walls)
    print(f"\n{images} images, median of {args.rounds} runs (best in brackets):\n")
    print("| pipeline | s / run | images/s | mbs / Python |")
    print("| --- | ---: | ---: | ---: |")
    print(f"| mbs-tool mono (whole command) | {mbs_s:.2f} ({min(mbs_times):.2f}) | {images / mbs_s:.2f} "
          f"({images / min(mbs_times):.2f}) | **{peer_s / mbs_s:.2f}x** ({min(peer_times) / min(mbs_times):.2f}x) |")
    print(f"| MfS-style Python, session to last write | {peer_s:.2f} ({min(peer_times):.2f}) | {images / peer_s:.2f} "
          f"({images / min(peer_times):.2f}) | 1.00x |")
    print(f"| MfS-style Python, whole process | {peer_wall:.2f} ({min(peer_walls):.2f}) | {images / peer_wall:.2f} "
          f"| {peer_wall / mbs_s:.2f}x |")

    middle = sorted(peer_stages, key=lambda r: r["seconds"])[len(peer_stages) // 2]
    print(f"\nPython's stages in its median run (ms / image; session creation {1000 * middle['load']:.0f} ms once):\n")
    print("| " + " | ".join(STAGES) + " |")
    print("|" + " ---: |" * len(STAGES))
    print("| " + " | ".join(f"{1000 * middle['stages'][s] / images:.1f}" for s in STAGES) + " |")
    no_sharpening = middle["seconds"] - middle["stages"]["sharpen"]
    print(f"\nWithout MfS's sharpening (which mbs does not do) Python would take {no_sharpening:.2f} s: "
          f"{images / no_sharpening:.2f} images/s, mbs / Python {no_sharpening / mbs_s:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
