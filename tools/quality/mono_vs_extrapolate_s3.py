#!/usr/bin/env python3
"""Helpers of tools/quality/mono_vs_extrapolate_s3.sh (needs numpy and Pillow).

  prep SHARED OUT   the training pairs and the held-out pairs, scaled
  table OUT         the Markdown tables of the `eval --json` files under OUT/eval,
                    and how close each set's disparities are to the truth

prep writes, under OUT:

- src/image_2/SCENE_K.png, src/image_3/SCENE_K.png: the training pairs, view K
  of Middlebury Baby2, Bowling2 and Laundry and its real partner K+1 (one
  step right), K = 0..5, at half size (2x2 box average after dropping an odd
  last row or column). `mono` reads src/image_2 only (one photo per pair),
  `extrapolate --kitti src` both.
- src/gt/SCENE_1.pfm, SCENE_5.pfm: the ground truth of views 1 and 5 (the
  photos of samples SCENE_1 and SCENE_5) for one step, at half size, to
  score the sets' own disparities (never used to train).
- heldout/teddy/{left,right}.png, gt.pfm: Teddy im2/im6 (4 steps apart) at
  half size, disparity disp2 / 4 / 2 (the mean of each 2x2 block whose four
  pixels are known, +inf elsewhere): 6.2 to 26.4 px.
- heldout/tsukuba/{left,right}.png, gt.pfm: Tsukuba col3/col4 at full size,
  truedisp / 16 (+inf where 0): 5 to 14 px.
"""

import json
import math
import os
import sys

import numpy as np
from PIL import Image

SCENES = ["baby2", "bowling2", "laundry"]
PAIRS_PER_SCENE = 6  # (view0, view1) ... (view5, view6)


def even(a):
    h, w = a.shape[:2]
    return a[: h // 2 * 2, : w // 2 * 2]


def half_rgb(path):
    a = even(np.asarray(Image.open(path).convert("RGB"), dtype=np.float64))
    h, w = a.shape[:2]
    a = a.reshape(h // 2, 2, w // 2, 2, 3).mean(axis=(1, 3))
    return Image.fromarray(np.clip(np.round(a), 0, 255).astype(np.uint8))


def half_disparity(path, codes_per_px):
    d = even(np.asarray(Image.open(path), dtype=np.float64))
    h, w = d.shape
    blocks = d.reshape(h // 2, 2, w // 2, 2)
    known = (blocks > 0).all(axis=(1, 3))
    mean = blocks.mean(axis=(1, 3)) / codes_per_px / 2.0
    return np.where(known, mean, np.inf).astype(np.float32)


def full_disparity(path, codes_per_px):
    d = np.asarray(Image.open(path), dtype=np.float64)
    return np.where(d > 0, d / codes_per_px, np.inf).astype(np.float32)


def write_pfm(path, d):
    h, w = d.shape
    with open(path, "wb") as f:
        f.write(f"Pf\n{w} {h}\n-1\n".encode())
        f.write(np.ascontiguousarray(d[::-1], dtype="<f4").tobytes())


def prep(shared, out):
    for side in ("image_2", "image_3"):
        os.makedirs(os.path.join(out, "src", side), exist_ok=True)
    for scene in SCENES:
        folder = os.path.join(shared, f"middlebury-{scene}")
        for k in range(PAIRS_PER_SCENE):
            name = f"{scene}_{k}.png"
            half_rgb(os.path.join(folder, f"view{k}.png")).save(os.path.join(out, "src/image_2", name))
            half_rgb(os.path.join(folder, f"view{k + 1}.png")).save(os.path.join(out, "src/image_3", name))
    gt = os.path.join(out, "src/gt")
    os.makedirs(gt, exist_ok=True)
    for scene in SCENES:
        folder = os.path.join(shared, f"middlebury-{scene}")
        for view in (1, 5):  # views with ground truth: one step = value / 12
            d = half_disparity(os.path.join(folder, f"disp{view}.png"), 12.0)
            write_pfm(os.path.join(gt, f"{scene}_{view}.pfm"), d)
    teddy = os.path.join(out, "heldout/teddy")
    os.makedirs(teddy, exist_ok=True)
    src = os.path.join(shared, "middlebury-teddy")
    half_rgb(os.path.join(src, "im2.png")).save(os.path.join(teddy, "left.png"))
    half_rgb(os.path.join(src, "im6.png")).save(os.path.join(teddy, "right.png"))
    write_pfm(os.path.join(teddy, "gt.pfm"), half_disparity(os.path.join(src, "disp2.png"), 4.0))
    tsukuba = os.path.join(out, "heldout/tsukuba")
    os.makedirs(tsukuba, exist_ok=True)
    src = os.path.join(shared, "middlebury-tsukuba-row3")
    Image.open(os.path.join(src, "scene1.row3.col3.ppm")).convert("RGB").save(os.path.join(tsukuba, "left.png"))
    Image.open(os.path.join(src, "scene1.row3.col4.ppm")).convert("RGB").save(os.path.join(tsukuba, "right.png"))
    write_pfm(os.path.join(tsukuba, "gt.pfm"), full_disparity(os.path.join(src, "truedisp.row3.col3.pgm"), 16.0))
    print(f"prep: {len(SCENES) * PAIRS_PER_SCENE} training pairs and 2 held-out pairs in {out}")


PAIRS = ["teddy", "tsukuba"]
LABELS = {
    "mono": "mono (FastDepth, single photos)",
    "ext": "extrapolate (real pairs)",
    "monodef": "mono, default range 5-15 %",
}
ARMS = [(a, LABELS[a]) for a in os.environ.get("ARMS", "mono ext").split()]
FIGURES = ["epe", "out2", "out3"]


def load(out):
    """{(name, pair): ALL figures} from OUT/eval/NAME.PAIR.json (`eval --json`)."""
    folder = os.path.join(out, "eval")
    scores = {}
    for file in sorted(os.listdir(folder)):
        if not file.endswith(".json"):
            continue
        name, pair = file[: -len(".json")].rsplit(".", 1)
        with open(os.path.join(folder, file)) as f:
            scores[(name, pair)] = json.load(f)["score"]["ALL"]
    return scores


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        d = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    assert kind == b"Pf", path
    return d.reshape(h, w)[::-1].astype(np.float64)


def diag(out):
    """How close each set's one-baseline disparity (camera 1, the photo) is
    to the truth, on the six photos with ground truth (views 1 and 5):
    EPE and Out-1 as they are, and after the best affine fit a d + b
    (least squares), which leaves the shape of the map."""
    print("| set | photos | EPE (px) | Out-1 | EPE after a d + b | Out-1 after | truth's range (px) |")
    print("| --- | --- | ---: | ---: | ---: | ---: | --- |")
    for arm in [a for a, _ in ARMS]:
        folder = os.path.join(out, "data", arm, "disparity_2")
        if not os.path.isdir(folder):
            continue
        raw, fit, out1, out1_fit, lo, hi = [], [], [], [], [], []
        for scene in SCENES:
            for view in (1, 5):
                gt = read_pfm(os.path.join(out, "data/src/gt", f"{scene}_{view}.pfm"))
                d = read_pfm(os.path.join(folder, f"{scene}_{view}.pfm"))
                ok = np.isfinite(gt) & np.isfinite(d)
                g, p = gt[ok], d[ok]
                a, b = np.linalg.lstsq(np.stack([p, np.ones_like(p)], 1), g, rcond=None)[0]
                raw.append(np.abs(p - g).mean())
                fit.append(np.abs(a * p + b - g).mean())
                out1.append((np.abs(p - g) > 1).mean() * 100)
                out1_fit.append((np.abs(a * p + b - g) > 1).mean() * 100)
                lo.append(g.min())
                hi.append(g.max())
        n = len(raw)
        print(
            f"| {LABELS[arm]} | {n} | {sum(raw) / n:.2f} | {sum(out1) / n:.1f} % | {sum(fit) / n:.2f} | "
            f"{sum(out1_fit) / n:.1f} % | {min(lo):.1f}-{max(hi):.1f} |"
        )


def mean_sd(values):
    m = sum(values) / len(values)
    if len(values) < 2:
        return (m, 0.0)
    sd = math.sqrt(sum((v - m) ** 2 for v in values) / (len(values) - 1))
    return (m, sd)


def fmt(m_sd, digits):
    m, sd = m_sd
    return f"{m:.{digits}f} ± {sd:.{digits}f}"


def table(out):
    scores = load(out)
    seeds = sorted({int(n.split("-s")[1].split("-")[0]) for n, _ in scores if n.startswith("floor-s")})
    steps = sorted({int(n.rsplit("-", 1)[1]) for n, _ in scores if n.startswith(ARMS[0][0] + "-s")})
    last = steps[-1]
    head = " | ".join(f"{p} EPE | {p} Out-2 | {p} Out-3" for p in PAIRS)
    print(f"| run | seed | {head} |")
    print("| --- | --- |" + " ---: |" * (3 * len(PAIRS)))

    def row(label, seed, name):
        line = " | ".join(
            f"{scores[(name, p)]['epe']:.2f} | {scores[(name, p)]['out2']:.1f} % | {scores[(name, p)]['out3']:.1f} %"
            for p in PAIRS
        )
        print(f"| {label} | {seed} | {line} |")

    row("built-in matcher (SGM, no training)", "-", "sgm")
    for seed in seeds:
        row("untrained (floor)", seed, f"floor-s{seed}-0")
    for arm, label in ARMS:
        for seed in seeds:
            row(f"{label}, step {last}", seed, f"{arm}-s{seed}-{last}")
    for name, label in [("floor", "untrained (floor)")] + [(a, f"{l}, step {last}") for a, l in ARMS]:
        step = 0 if name == "floor" else last
        parts = []
        for p in PAIRS:
            for fig, digits, unit in [("epe", 2, ""), ("out2", 1, " %"), ("out3", 1, " %")]:
                values = [scores[(f"{name}-s{s}-{step}", p)][fig] for s in seeds]
                parts.append(fmt(mean_sd(values), digits) + unit)
        print(f"| **{label}, mean ± SD** | {len(seeds)} seeds | " + " | ".join(parts) + " |")
    print()
    print("Mean over the seeds at each checkpoint (EPE px / Out-3 %):")
    print()
    print("| step | " + " | ".join(f"{label}: {p}" for _, label in ARMS for p in PAIRS) + " |")
    print("| --- |" + " --- |" * (len(ARMS) * len(PAIRS)))
    for step in [0] + steps:
        parts = []
        for arm, _ in ARMS:
            for p in PAIRS:
                names = [f"floor-s{s}-0" if step == 0 else f"{arm}-s{s}-{step}" for s in seeds]
                epe = sum(scores[(n, p)]["epe"] for n in names) / len(names)
                out3 = sum(scores[(n, p)]["out3"] for n in names) / len(names)
                parts.append(f"{epe:.2f} / {out3:.1f}")
        print(f"| {step} | " + " | ".join(parts) + " |")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "prep":
        prep(sys.argv[2], sys.argv[3])
    elif len(sys.argv) == 3 and sys.argv[1] == "table":
        table(sys.argv[2])
        print()
        diag(sys.argv[2])
    else:
        sys.exit(__doc__)
