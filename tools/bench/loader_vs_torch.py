#!/usr/bin/env python3
"""Training data loading at MBS20K scale: mbs-train's `BatchLoader`, and
`mbs.torch.MultiBaselineDataset` under a PyTorch `DataLoader`, against the
`DataLoader` a user of the authors' code would write, in the same run, on
the same files.

Both draw per item a sample, three distinct views of it (reference,
student and teacher targets) and one 384x512 crop, decode the three
960x540 PNG views, crop them and stack batches of 16 as float32
`[16, 3, 3, 384, 512]` (mbs: three `[16, 3, 384, 512]` tensors) in [0, 1].

- mbs: the release example `loader_throughput --manifest M --workers W`
  (crates/mbs-train/examples/loader_throughput.rs), W loading threads;
- mbs.torch: `DataLoader(MultiBaselineDataset(...), batch_size=None,
  num_workers=W)`, one item per step decoded and cropped in Rust with the
  draws of the student's augmentation (which the training loop applies
  where the network runs);
- PyTorch: `torch.utils.data.DataLoader(num_workers=W, batch_size=16)` over
  a map-style `Dataset` decoding with `cv2.imread` (BGR to RGB), as the
  official RAFT-Stereo and IGEV-Stereo loaders do.

The data are rendered first with `mbs-tool synth` (six 5-view scenes at
960x540, one town for training) unless --manifest names a real set. Both
loaders make one untimed pass first, so the files are in the page cache as
in a long run, then time --steps batches per worker count.

Needs PyTorch, OpenCV and the package (`pip install torch
opencv-python-headless ./python`; not part of CI). From the repository root:
    python3 tools/bench/loader_vs_torch.py --workers 1,2 --steps 12
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def cargo_executable(package, kind, name):
    """Builds a release binary or example and returns its path (cargo's own report)."""
    command = ["cargo", "build", "--release", "-p", package, f"--{kind}", name,
               "--message-format=json-render-diagnostics"]
    out = subprocess.run(command, cwd=ROOT, check=True, stdout=subprocess.PIPE, text=True)
    for line in out.stdout.splitlines():
        message = json.loads(line)
        if message.get("reason") == "compiler-artifact" and message["target"]["name"] == name:
            if message.get("executable"):
                return message["executable"]
    sys.exit(f"cargo built no {name} executable")


def render(root, frames, tool):
    subprocess.run([tool, "synth", "--out", str(root), "--frames", str(frames),
                    "--towns", "Town01,Town10", "--weathers", "ClearNoon", "--test-towns", "Town10",
                    "--supersample", "1", "--no-checksums", "--seed", "7"],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return root / "manifest.json"


class TripletCrops:
    """Items of three views of a training sample, one random crop each item."""

    def __init__(self, manifest, crop, length, seed):
        import numpy as np

        document = json.loads(Path(manifest).read_text())
        folder = Path(manifest).parent
        self.samples = [[str(folder / view) for view in sample["views"]]
                        for sample in document["samples"] if sample["split"] == "train"]
        if not self.samples:
            sys.exit(f"{manifest}: no training samples")
        self.width, self.height = document["rig"]["width"], document["rig"]["height"]
        self.crop, self.length, self.seed = crop, length, seed
        self.np = np

    def __len__(self):
        return self.length

    def __getitem__(self, index):
        import cv2
        import torch

        rng = self.np.random.default_rng((self.seed, index))
        views = self.samples[rng.integers(len(self.samples))]
        chosen = rng.choice(len(views), size=3, replace=False)
        height, width = self.crop
        top = rng.integers(self.height - height + 1)
        left = rng.integers(self.width - width + 1)
        images = []
        for view in chosen:
            image = cv2.imread(views[view], cv2.IMREAD_COLOR)
            if image is None:
                raise FileNotFoundError(views[view])
            window = image[top:top + height, left:left + width, ::-1]
            images.append(torch.from_numpy(window.transpose(2, 0, 1).astype(self.np.float32) / 255.0))
        return torch.stack(images)


def torch_samples_per_s(manifest, crop, batch, steps, workers):
    import torch

    def one_pass():
        dataset = TripletCrops(manifest, crop, batch * steps, seed=1)
        loader = torch.utils.data.DataLoader(dataset, batch_size=batch, num_workers=workers, shuffle=False)
        start = time.perf_counter()
        for items in loader:
            assert items.shape == (batch, 3, 3, *crop)
        return time.perf_counter() - start

    one_pass()  # warms the page cache
    return batch * steps / one_pass()


def dataset_samples_per_s(manifest, crop, batch, steps, workers):
    import torch
    from mbs.torch import MultiBaselineDataset

    def one_pass():
        dataset = MultiBaselineDataset(manifest, steps, batch, crop, seed=1)
        loader = torch.utils.data.DataLoader(dataset, batch_size=None, num_workers=workers)
        start = time.perf_counter()
        for items in loader:
            assert items["reference"].shape == (batch, 3, *crop)
        return time.perf_counter() - start

    one_pass()  # warms the page cache
    return batch * steps / one_pass()


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--manifest", help="a real dataset's manifest (default: render six scenes)")
    parser.add_argument("--workers", default="1,2", help="comma-separated loading thread/process counts")
    parser.add_argument("--steps", type=int, default=12, help="timed batches per worker count")
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--mbs-tool", metavar="EXE", help="render with this mbs-tool instead of building it")
    args = parser.parse_args()
    try:
        import cv2  # noqa: F401
        import mbs  # noqa: F401
        import torch  # noqa: F401
    except ImportError as missing:
        sys.exit(f"{missing}: this benchmark needs pip install torch opencv-python-headless ./python "
                 "(not part of CI)")
    workers = [int(w) for w in args.workers.split(",")]
    crop = (384, 512)
    with tempfile.TemporaryDirectory() as scratch:
        if args.manifest:
            manifest = Path(args.manifest)
        else:
            tool = args.mbs_tool or cargo_executable("mbs-tool", "bin", "mbs-tool")
            manifest = render(Path(scratch), 6, tool)
        example = cargo_executable("mbs-train", "example", "loader_throughput")
        load_before = os.getloadavg()
        out = subprocess.run([example, "--manifest", str(manifest), "--workers", args.workers,
                              "--steps", str(args.steps), "--batch", str(args.batch)],
                             check=True, stdout=subprocess.PIPE, text=True).stdout
        mbs = {line["workers"]: line["samples_per_s"] for line in map(json.loads, out.splitlines())}
        dataset = {w: dataset_samples_per_s(manifest, crop, args.batch, args.steps, w) for w in workers}
        peer = {w: torch_samples_per_s(manifest, crop, args.batch, args.steps, w) for w in workers}
        load_after = os.getloadavg()
    import torch

    print(f"batch {args.batch}, crop {crop[0]}x{crop[1]}, {args.steps} batches, torch {torch.__version__}, "
          f"load average {load_before[0]:.2f} before / {load_after[0]:.2f} after\n")
    print("| loading threads / DataLoader workers | mbs samples/s | mbs.torch dataset samples/s "
          "| cv2 + numpy dataset samples/s | mbs / cv2 | mbs.torch / cv2 |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: |")
    for w in workers:
        print(f"| {w} | {mbs[w]:.1f} | {dataset[w]:.1f} | {peer[w]:.1f} | {mbs[w] / peer[w]:.2f} "
              f"| {dataset[w] / peer[w]:.2f} |")


if __name__ == "__main__":
    main()
