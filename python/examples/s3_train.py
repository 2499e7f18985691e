#!/usr/bin/env python3
"""Trains a PyTorch stereo network with S3 on an mbs manifest, no ground
truth: batches from ``MultiBaselineDataset`` (the triplets, crops and
augmentation of ``mbs-tool train``), an EMA teacher, ``S3Loss``, Adam with
a one-cycle learning rate and gradient clipping, as the paper's recipe.

Any network works whose ``forward(left, right)`` takes ``[B, 3, H, W]``
images in ``[0, 1]`` (target on the right) and returns the disparity of
the left image, ``[B, 1, H, W]`` or ``[B, H, W]`` in pixels, or a list of
them (an iterative network, supervised with the sequence weights). Pass it
as ``--network package.module:ClassName`` (built with no arguments); the
default is a small cost-volume network defined below.

    mbs-tool synth --out synth --frames 8 --width 256 --height 128 --focal 128
    python3 python/examples/s3_train.py synth/manifest.json --steps 500 \\
        --batch-size 4 --crop 96x192 --log train.jsonl

It runs on the GPU when PyTorch sees one (``--device cuda:1`` picks
another, ``--device cpu`` the CPU); ``--precision bf16|f16`` runs the
networks under autocast on that device (f16 with a grad scaler), the loss
in f32, and a GPU run ends with its peak GPU memory.

Each step prints (and ``--log`` writes as a JSON line) the loss, its
terms, the student's and teacher's mask shares and the learning rate.
Before the first step and after the last, the teacher is scored on the
manifest's held-out samples (``val``, else ``test``) that have ground
truth for the pair of views 0 and 1: EPE and Out-3 over valid pixels, and
the self-supervised photometric error of the warp over all pixels (a
``{"eval": ...}`` line in the log). The training loss itself is no score:
its masked terms grow as the masks do, and the geometry term follows a
moving teacher.
"""

import argparse
import copy
import importlib
import json
import sys
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn
from torch.utils.data import DataLoader

import mbs
from mbs.torch import (
    MultiBaselineDataset,
    S3Loss,
    augment_batch,
    cosine_momentum,
    ema_update_,
    geometry_weight,
    photometric_map,
    predict,
    warp_to_reference,
)


class CostVolumeNet(nn.Module):
    """A small stereo network: shared features at 1/4 resolution, a
    correlation volume over ``max_disparity / 4`` candidates, two
    convolutions over it, a soft-argmin and bilinear upsampling."""

    def __init__(self, max_disparity: int = 48, features: int = 16, hidden: int = 32):
        super().__init__()
        self.candidates = max_disparity // 4
        self.features = nn.Sequential(
            nn.Conv2d(3, features // 2, 3, 2, 1),
            nn.ReLU(),
            nn.Conv2d(features // 2, features, 3, 2, 1),
            nn.ReLU(),
            nn.Conv2d(features, features, 3, 1, 1),
        )
        self.aggregate = nn.Sequential(
            nn.Conv2d(self.candidates + features, hidden, 3, 1, 1),
            nn.ReLU(),
            nn.Conv2d(hidden, self.candidates, 3, 1, 1),
        )

    def forward(self, left, right):
        height, width = left.shape[2:]
        both = self.features(torch.cat([left, right]) * 2.0 - 1.0)
        left_f, right_f = F.normalize(both, dim=1).chunk(2)
        shifted = F.pad(right_f, (self.candidates - 1, 0))
        quarter_width = left_f.shape[3]
        volume = torch.cat(
            [
                (left_f * shifted[..., self.candidates - 1 - d : self.candidates - 1 - d + quarter_width]).sum(
                    1, keepdim=True
                )
                for d in range(self.candidates)
            ],
            1,
        )
        logits = self.aggregate(torch.cat([volume, left_f], 1)) + volume * 10.0
        values = torch.arange(self.candidates, dtype=left.dtype, device=left.device).view(1, -1, 1, 1)
        quarter = (logits.softmax(1) * values).sum(1, keepdim=True) * 4.0
        return F.interpolate(quarter, size=(height, width), mode="bilinear", align_corners=False)


def load_network(spec: str) -> nn.Module:
    """``module:Class`` built with no arguments, or the default network."""
    if spec == "cost-volume":
        return CostVolumeNet()
    module, _, name = spec.partition(":")
    if not name:
        raise SystemExit(f"--network {spec}: expected package.module:ClassName")
    return getattr(importlib.import_module(module), name)()


def held_out_pairs(manifest):
    """(left, right, ground truth) of the held-out samples' pair (0, 1)."""
    parsed = mbs.load_manifest(manifest)
    root = Path(manifest).parent
    splits = {s["split"] for s in parsed["samples"]}
    split = "val" if "val" in splits else "test"
    pairs = []
    for sample in parsed["samples"]:
        truth = [g for g in sample.get("ground_truth", []) if (g["reference"], g["target"]) == (0, 1)]
        if sample["split"] == split and truth:
            disparity = mbs.read_pfm(root / truth[0]["disparity"]) * truth[0].get("scale", 1.0)
            views = [mbs.read_rgb(root / sample["views"][v]) for v in (0, 1)]
            pairs.append((*views, disparity))
    return pairs


@torch.no_grad()
def evaluate(network, pairs, device):
    """EPE (px) and Out-3 (%) of ``network`` over the pairs' valid pixels,
    and its self-supervised error: the photometric error (the loss's ``P``,
    over every pixel, no mask) of the right view warped by its disparity."""
    errors, photometric = [], []
    for left, right, truth in pairs:
        image = lambda array: torch.from_numpy(array).permute(2, 0, 1)[None].float().div(255).to(device)  # noqa: E731
        left_image, right_image = image(left), image(right)
        disparity = predict(network, left_image, right_image, ["right"])[-1]
        signs = torch.ones(1, 1, 1, 1, device=device)
        warped = warp_to_reference(right_image, disparity, signs)
        photometric.append(photometric_map(left_image, warped, 0.85, 7).mean().item())
        valid = np.isfinite(truth)
        errors.append(np.abs(disparity[0, 0].cpu().numpy() - truth)[valid])
    errors = np.concatenate(errors) if errors else np.array([np.nan])
    return {
        "epe": float(errors.mean()),
        "out3": float((errors > 3).mean() * 100),
        "photometric": float(np.mean(photometric)),
    }


def crop_size(text: str):
    height, _, width = text.partition("x")
    return int(height), int(width)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("manifest", help="an mbs manifest (mbs-tool synth, scan)")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--batch-size", type=int, default=4)
    parser.add_argument("--crop", type=crop_size, default=(96, 192), help="HEIGHTxWIDTH (default 96x192)")
    parser.add_argument("--lr", type=float, default=1e-3, help="peak learning rate (paper: 2e-4)")
    parser.add_argument("--ema-base", type=float, default=0.996, help="EMA momentum at step 0")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2, help="DataLoader worker processes")
    parser.add_argument("--network", default="cost-volume", help="module:Class, or the built-in cost-volume")
    parser.add_argument(
        "--geometry-start",
        type=float,
        default=0.0,
        help="share of the run before the geometry term (0.3 for RAFT/IGEV-Stereo from scratch)",
    )
    parser.add_argument("--geometry-warmup", type=float, default=0.0, help="share over which it then rises")
    parser.add_argument("--log", help="write each step's losses here as JSON lines")
    parser.add_argument("--save", help="write the teacher's state_dict here at the end")
    parser.add_argument("--device", help="torch device, e.g. cuda:1 (default: cuda when PyTorch sees a GPU, else cpu)")
    parser.add_argument(
        "--precision",
        choices=["f32", "bf16", "f16"],
        default="f32",
        help="the networks under autocast in this format on the device (f16 with a grad scaler); the loss stays f32",
    )
    args = parser.parse_args(argv)

    torch.manual_seed(args.seed)
    # Denormal floats make CPU arithmetic up to 100x slower; they carry nothing here.
    torch.set_flush_denormal(True)
    device = torch.device(args.device or ("cuda" if torch.cuda.is_available() else "cpu"))
    if device.type == "cuda" and not torch.cuda.is_available():
        parser.error(f"--device {device}: PyTorch sees no CUDA device")
    autocast_dtype = {"f32": None, "bf16": torch.bfloat16, "f16": torch.float16}[args.precision]

    def autocast():
        return torch.autocast(device.type, dtype=autocast_dtype, enabled=autocast_dtype is not None)

    scaler = torch.amp.GradScaler(device.type, enabled=args.precision == "f16")
    student = load_network(args.network).to(device)
    teacher = copy.deepcopy(student).requires_grad_(False)
    loss_fn = S3Loss()
    optimiser = torch.optim.Adam(student.parameters(), lr=args.lr)
    schedule = torch.optim.lr_scheduler.OneCycleLR(
        optimiser, args.lr, total_steps=args.steps, pct_start=0.01, cycle_momentum=False, anneal_strategy="linear"
    )
    data = MultiBaselineDataset(args.manifest, args.steps, args.batch_size, args.crop, args.seed)
    loader = DataLoader(data, batch_size=None, num_workers=args.workers)
    log = open(args.log, "w") if args.log else None
    pairs = held_out_pairs(args.manifest)

    def score(step):
        scores = {"step": step, **evaluate(teacher, pairs, device)}
        print(
            f"held-out after {step} steps: EPE {scores['epe']:.2f} px, Out-3 {scores['out3']:.1f} %, "
            f"photometric error {scores['photometric']:.4f}",
            flush=True,
        )
        if log:
            log.write(json.dumps({"eval": scores}) + "\n")

    score(0)
    for batch in loader:
        step = batch["step"]
        images = {
            name: batch[name].to(device)
            for name in [
                "reference",
                "student_target",
                "teacher_target",
                "brightness",
                "contrast",
                "saturation",
                "occlusion",
            ]
        }
        images["augmented_reference"], images["augmented_target"] = augment_batch(images)
        with torch.no_grad(), autocast():
            teacher_disparity = predict(teacher, images["reference"], images["teacher_target"], batch["teacher_sides"])[
                -1
            ].float()
        with autocast():
            student_disparities = predict(
                student, images["augmented_reference"], images["augmented_target"], batch["student_sides"]
            )
        student_disparities = [d.float() for d in student_disparities]
        out = loss_fn(
            images["reference"],
            images["student_target"],
            images["teacher_target"],
            student_disparities,
            teacher_disparity,
            batch["student_sides"],
            batch["teacher_sides"],
            batch["ratios"].to(device),
            geometry_weight=geometry_weight(step, args.steps, args.geometry_start, args.geometry_warmup),
        )
        optimiser.zero_grad()
        scaler.scale(out.total).backward()
        scaler.unscale_(optimiser)
        torch.nn.utils.clip_grad_norm_(student.parameters(), 1.0)
        scaler.step(optimiser)
        scaler.update()
        schedule.step()
        ema_update_(teacher, student, cosine_momentum(step, args.steps, args.ema_base))
        record = {
            "step": step + 1,
            "loss": out.total.item(),
            "photometric": out.photometric.item(),
            "geometry": out.geometry.item(),
            "smoothness": out.smoothness.item(),
            "student_mask": out.student_mask.mean().item(),
            "teacher_mask": out.teacher_mask.mean().item(),
            "lr": schedule.get_last_lr()[0],
        }
        print(" ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in record.items()), flush=True)
        if log:
            log.write(json.dumps(record) + "\n")
    score(args.steps)
    if device.type == "cuda":
        print(
            f"peak GPU memory {torch.cuda.max_memory_allocated(device) / 2**20:.0f} MiB "
            f"({torch.cuda.get_device_name(device)})",
            flush=True,
        )
    if log:
        log.close()
    if args.save:
        torch.save(teacher.state_dict(), args.save)


if __name__ == "__main__":
    sys.exit(main())
