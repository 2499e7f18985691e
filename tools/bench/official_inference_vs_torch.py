#!/usr/bin/env python3
"""Inference of the full-size IGEV-Stereo (or RAFT-Stereo) on KITTI-size
pairs (1242x375, padded to multiples of 32 as the official InputPadder):
`mbs-tool predict --backbone X --weights W` against the official PyTorch
model's forward (test mode, 32 iterations) with the same weights, on the
CPU, 2 threads each, each in its own process (issue 29).

The weights are the official network's own random initialisation
(seeded), saved as a state dict that `--weights` loads: no download. The
pairs are smooth random textures with a horizontal shift, written as a
KITTI 2015 testing folder (image_2, image_3, *_10.png).

- mbs: `predict --kitti DIR` over FRAMES pairs, timed by its own report
  ("N done ... in S s"), which excludes loading the weights; one extra
  first pair warms up (a run over 1 pair is subtracted).
- PyTorch: `model(left, right, iters=32, test_mode=True)` under no_grad,
  one warm-up pair, then FRAMES timed.

Needs PyTorch and the official code (never in CI; IGEV also timm 0.5.4):
    git clone https://github.com/gangweiX/IGEV /tmp/IGEV
    python3 tools/bench/official_inference_vs_torch.py --network igev --official /tmp/IGEV/IGEV-Stereo
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
WIDTH, HEIGHT = 1242, 375


def official_model(network, official, seed):
    import torch

    sys.path.insert(0, str(official))
    torch.manual_seed(seed)
    if network == "igev":
        import timm

        create = timm.create_model
        timm.create_model = lambda name, pretrained=False, **kw: create(name, pretrained=False, **kw)
        from core.igev_stereo import IGEVStereo

        args = argparse.Namespace(hidden_dims=[128] * 3, n_gru_layers=3, corr_levels=2, corr_radius=4,
                                  n_downsample=2, max_disp=192, mixed_precision=False,
                                  precision_dtype="float32")
        return IGEVStereo(args).eval()
    from core.raft_stereo import RAFTStereo

    args = argparse.Namespace(hidden_dims=[128] * 3, n_gru_layers=3, corr_levels=4, corr_radius=4,
                              n_downsample=2, context_norm="batch", slow_fast_gru=False,
                              shared_backbone=False, corr_implementation="reg", mixed_precision=False)
    return RAFTStereo(args).eval()


def write_pairs(root, frames, seed):
    import numpy as np
    from PIL import Image

    rng = np.random.default_rng(seed)
    for name in ("image_2", "image_3"):
        (root / name).mkdir(parents=True, exist_ok=True)
    for frame in range(frames):
        coarse = rng.random((HEIGHT // 8 + 2, WIDTH // 8 + 40, 3))
        big = np.kron(coarse, np.ones((8, 8, 1)))[:HEIGHT, :WIDTH + 160]
        left = (255 * big[:, 80:80 + WIDTH]).astype(np.uint8)
        right = (255 * big[:, 60:60 + WIDTH]).astype(np.uint8)
        Image.fromarray(left).save(root / "image_2" / f"{frame:06d}_10.png")
        Image.fromarray(right).save(root / "image_3" / f"{frame:06d}_10.png")


def torch_worker(args):
    import numpy as np
    import torch
    from PIL import Image

    torch.set_num_threads(args.threads)
    model = official_model(args.network, args.official, args.seed)
    pad_h, pad_w = (-HEIGHT) % 32, (-WIDTH) % 32

    def load(path):
        image = torch.from_numpy(np.array(Image.open(path))).permute(2, 0, 1).float()[None]
        return torch.nn.functional.pad(image, [pad_w // 2, pad_w - pad_w // 2, pad_h // 2, pad_h - pad_h // 2],
                                       mode="replicate")

    frames = sorted((args.data / "image_2").glob("*_10.png"))
    times = []
    with torch.no_grad():
        for path in frames:
            left, right = load(path), load(args.data / "image_3" / path.name)
            start = time.perf_counter()
            model(left, right, iters=32, test_mode=True)
            times.append(time.perf_counter() - start)
    timed = times[1:]
    print(json.dumps({"framework": "torch", "s_per_pair": sum(timed) / len(timed)}))


def mbs_seconds(tool, network, weights, data, out, threads):
    env = {**os.environ, "RAYON_NUM_THREADS": str(threads)}
    result = subprocess.run([str(tool), "predict", "--kitti", str(data), "--out", str(out), "--backbone", network,
                             "--weights", str(weights), "--overwrite"],
                            env=env, check=True, stderr=subprocess.PIPE, text=True)
    match = re.search(r"(\d+) done.* in ([0-9.]+) s", result.stderr)
    if not match:
        sys.exit(f"cannot read predict's timing from:\n{result.stderr}")
    return int(match.group(1)), float(match.group(2))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--network", choices=["raft-stereo", "igev"], default="igev")
    parser.add_argument("--official", type=Path, required=True)
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--tool", type=Path, default=ROOT / "target/release/mbs-tool")
    parser.add_argument("--torch-worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--data", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.torch_worker:
        torch_worker(args)
        return
    import torch

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        weights = tmp / "weights.pth"
        torch.save(official_model(args.network, args.official, args.seed).state_dict(), weights)
        one, many = tmp / "one" / "testing", tmp / "many" / "testing"
        write_pairs(one, 1, args.seed)
        write_pairs(many, args.frames + 1, args.seed)
        load_before = os.getloadavg()[0]
        _, first = mbs_seconds(args.tool, args.network, weights, one, tmp / "out1", args.threads)
        pairs, total = mbs_seconds(args.tool, args.network, weights, many, tmp / "out", args.threads)
        ours = (total - first) / (pairs - 1)
        out = subprocess.run([sys.executable, __file__, "--torch-worker", "--network", args.network, "--official",
                              str(args.official), "--threads", str(args.threads), "--seed", str(args.seed),
                              "--data", str(many)], check=True, stdout=subprocess.PIPE, text=True).stdout
        theirs = json.loads(out.splitlines()[-1])["s_per_pair"]
    print(f"{args.network}, {WIDTH}x{HEIGHT} padded to multiples of 32, 32 iterations, {args.threads} threads, "
          f"torch {torch.__version__}, load average {load_before:.2f} before / {os.getloadavg()[0]:.2f} after\n")
    print("| network | mbs predict s/pair | PyTorch forward s/pair | mbs / PyTorch |")
    print("| --- | ---: | ---: | ---: |")
    print(f"| {args.network} | {ours:.2f} | {theirs:.2f} | {ours / theirs:.2f} |")


if __name__ == "__main__":
    main()
