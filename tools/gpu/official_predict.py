#!/usr/bin/env python3
"""The official RAFT-Stereo predicting one pair with weights that
`mbs-tool export` wrote, on a torch device, for the GPU check's predict
phase (tools/gpu/run.py): builds `RAFTStereo` with the run's
`network.raft_stereo` settings, loads the safetensors strictly, runs the
test iterations on the pair (padded to a multiple of 32 and cropped back,
as the official demo), writes the disparity as a PFM and prints one JSON
line with the time. Needs PyTorch, safetensors and the official code."""

import argparse
import json
import struct
import sys
import time
from pathlib import Path


def read_png_rgb(path):
    """A PNG as a float tensor [1, 3, H, W] in 0..255 (through torchvision
    when it is there, else imageio or PIL)."""
    import numpy as np
    import torch

    try:
        from PIL import Image

        array = np.asarray(Image.open(path).convert("RGB"))
    except ImportError:
        import cv2

        array = cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return torch.from_numpy(array.copy()).permute(2, 0, 1)[None].float()


def write_pfm(path, rows):
    height, width = len(rows), len(rows[0])
    with open(path, "wb") as f:
        f.write(f"Pf\n{width} {height}\n-1.0\n".encode())
        for row in reversed(rows):
            f.write(struct.pack(f"<{width}f", *row))


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--official", type=Path, required=True)
    parser.add_argument("--weights", type=Path, required=True)
    parser.add_argument("--config", type=Path, required=True, help="the run's config.json")
    parser.add_argument("--left", type=Path, required=True)
    parser.add_argument("--right", type=Path, required=True)
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    import torch
    import torch.nn.functional as F
    from safetensors.torch import load_file

    sys.path.insert(0, str(args.official))
    from core.raft_stereo import RAFTStereo

    settings = json.loads(args.config.read_text())["network"]["raft_stereo"]
    official = argparse.Namespace(
        hidden_dims=[settings["hidden_dim"]] * 3, n_gru_layers=settings["gru_levels"],
        corr_levels=settings["corr_levels"], corr_radius=settings["corr_radius"],
        n_downsample=settings["n_downsample"], context_norm=settings["context_norm"],
        slow_fast_gru=settings["slow_fast_gru"], shared_backbone=False, corr_implementation="reg",
        mixed_precision=False)
    device = torch.device(args.device)
    model = RAFTStereo(official)
    state = {k: v for k, v in load_file(str(args.weights)).items() if not k.endswith("num_batches_tracked")}
    missing, unexpected = model.load_state_dict(state, strict=False)
    if missing or unexpected:
        sys.exit(f"{args.weights}: missing {missing[:5]}, unexpected {unexpected[:5]}")
    model.to(device).eval()
    left, right = read_png_rgb(args.left).to(device), read_png_rgb(args.right).to(device)
    height, width = left.shape[2:]
    pad_h, pad_w = (-height) % 32, (-width) % 32
    padding = (pad_w // 2, pad_w - pad_w // 2, pad_h // 2, pad_h - pad_h // 2)
    left, right = F.pad(left, padding, mode="replicate"), F.pad(right, padding, mode="replicate")
    with torch.no_grad():
        start = time.perf_counter()
        _, flow = model(left, right, iters=settings["test_iters"], test_mode=True)
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        seconds = time.perf_counter() - start
    disparity = -flow[0, 0, padding[2] : padding[2] + height, padding[0] : padding[0] + width]
    write_pfm(args.out, disparity.float().cpu().tolist())
    print(json.dumps({"framework": "torch", "device": str(device), "seconds": round(seconds, 3),
                      "torch_version": torch.__version__}))


if __name__ == "__main__":
    main()
