#!/usr/bin/env python3
"""S3 training step of RAFT-Stereo or IGEV-Stereo in mbs-train (burn, flex
CPU backend) against the same step with the official PyTorch network on the
CPU, in the same run, same batch, crop and iteration counts.

- burn: the release example `step_time --backbone raft-stereo|igev`
  (crates/mbs-train/examples/step_time.rs): `S3Trainer::step`,
  RAYON_NUM_THREADS=THREADS;
- PyTorch: the official `RAFTStereo` or `IGEVStereo` (a checkout given with
  --official; batch norm frozen as in mbs, IGEV's feature encoder built
  with pretrained=False) in the step of tools/bench/s3_torch.py: teacher
  forward under no_grad with the test iterations, student forward with the
  training iterations, the S3 loss of every student prediction (IGEV's
  initial disparity first) weighted as the official sequence loss (gamma
  0.9 adjusted to 0.9^(15/(n-1))), backward, clipping, Adam (eps 1e-8),
  EMA; torch.set_num_threads(THREADS).

Both take random images with a fixed seed, WARMUP untimed steps, then STEPS
timed steps, each in its own process; peak RSS is that process's VmHWM.

`--device cuda` runs both on a GPU (mbs's `step_time` built with
`--features cuda`, given with --no-build; PyTorch with its timers
synchronised and its peak GPU memory); `--precision bf16|f16` runs both
networks in mixed precision (PyTorch: autocast on the device, f16 with a
grad scaler, and the official `mixed_precision` switch on, whose CUDA
autocast blocks are f16 in RAFT-Stereo whatever the format).
`--torch-only` skips mbs (the GPU check runs mbs itself).

Needs PyTorch and the official code (never in CI; IGEV also timm 0.5.4):
    git clone https://github.com/princeton-vl/RAFT-Stereo /tmp/RAFT-Stereo
    python3 tools/bench/official_step_vs_torch.py --network raft-stereo --official /tmp/RAFT-Stereo
    git clone https://github.com/gangweiX/IGEV /tmp/IGEV
    python3 tools/bench/official_step_vs_torch.py --network igev --official /tmp/IGEV/IGEV-Stereo
"""

import argparse
import copy
import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from train_step_vs_torch import build_example, run_json  # noqa: E402


def rss_mib(field):
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024.0
    return None


def sequence_weights(n, gamma=0.9):
    if n == 1:
        return [1.0]
    adjusted = gamma ** (15.0 / (n - 1))
    return [adjusted ** (n - 1 - i) for i in range(n)]


def torch_worker(args):
    import torch

    sys.path.insert(0, str(HERE))
    sys.path.insert(0, str(args.official))
    import s3_torch

    device = torch.device(args.device)
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    if args.network == "igev":
        import timm

        create = timm.create_model
        timm.create_model = lambda name, pretrained=False, **kw: create(name, pretrained=False, **kw)
        from core.igev_stereo import IGEVStereo

        official = argparse.Namespace(
            hidden_dims=[args.hidden_dim] * 3, n_gru_layers=args.gru_levels, corr_levels=2, corr_radius=4,
            n_downsample=2, max_disp=192, mixed_precision=args.precision != "f32",
            precision_dtype={"f32": "float32", "bf16": "bfloat16", "f16": "float16"}[args.precision])
        student = IGEVStereo(official)
    else:
        from core.raft_stereo import RAFTStereo

        official = argparse.Namespace(
            hidden_dims=[args.hidden_dim] * 3, n_gru_layers=args.gru_levels, corr_levels=4, corr_radius=4,
            n_downsample=args.n_downsample, context_norm="batch", slow_fast_gru=False, shared_backbone=False,
            corr_implementation="reg", mixed_precision=args.precision != "f32")
        student = RAFTStereo(official)
    # mbs freezes every batch norm (RAFT-Stereo has 2-D ones only).
    student.train()
    for module in student.modules():
        if isinstance(module, torch.nn.modules.batchnorm._BatchNorm):
            module.eval()
    student.to(device)
    teacher = copy.deepcopy(student).requires_grad_(False).eval()
    autocast_dtype = {"f32": None, "bf16": torch.bfloat16, "f16": torch.float16}[args.precision]
    scaler = torch.amp.GradScaler(device.type) if args.precision == "f16" else None

    def autocast():
        return torch.autocast(device.type, dtype=autocast_dtype, enabled=autocast_dtype is not None)

    def final(net, reference, target):
        out = net(reference * 255.0, target * 255.0, iters=args.test_iters, test_mode=True)
        return out if args.network == "igev" else -out[1]

    def every(net, reference, target):
        out = net(reference * 255.0, target * 255.0, iters=args.train_iters)
        if args.network == "igev":
            return [out[0]] + list(out[1])
        return [-f for f in out]

    loss = s3_torch.S3Loss()
    optimizer = torch.optim.Adam(student.parameters(), lr=2e-4, betas=(0.9, 0.999), eps=1e-8)
    batch = s3_torch.make_batch(args.batch, args.height, args.width, device)
    weights = sequence_weights(args.train_iters + (1 if args.network == "igev" else 0))

    def step(index):
        with torch.no_grad(), autocast():
            d_t = s3_torch.predict(lambda r, t: final(teacher, r, t), batch["reference"],
                                   batch["teacher_target"], batch["teacher_sides"])
        d_t = d_t.float()
        sides = batch["student_sides"]
        with autocast():
            predictions = every(student, s3_torch.mirror_left(batch["augmented_reference"], sides),
                                s3_torch.mirror_left(batch["augmented_target"], sides))
        total = 0.0
        for weight, d_s in zip(weights, predictions):
            total = total + weight * loss(batch["reference"], batch["student_target"], batch["teacher_target"],
                                          s3_torch.mirror_left(d_s.float(), sides), d_t, sides,
                                          batch["teacher_sides"], batch["ratios"])
        value = total.item()
        optimizer.zero_grad(set_to_none=True)
        (total if scaler is None else scaler.scale(total)).backward()
        if scaler is not None:
            scaler.unscale_(optimizer)
        torch.nn.utils.clip_grad_norm_(student.parameters(), 1.0)
        for group in optimizer.param_groups:
            group["lr"] = s3_torch.one_cycle_lr(index, 2e-4, args.warmup + args.steps + 100)
        if scaler is None:
            optimizer.step()
        else:
            scaler.step(optimizer)
            scaler.update()
        momentum = s3_torch.cosine_momentum(index, 0.996, args.warmup + args.steps + 100)
        with torch.no_grad():
            for t, s in zip(teacher.parameters(), student.parameters()):
                t.mul_(momentum).add_(s, alpha=1.0 - momentum)
        return value

    before = rss_mib("VmRSS")
    for i in range(args.warmup):
        step(i)
    if device.type == "cuda":
        torch.cuda.reset_peak_memory_stats(device)
    s3_torch.synchronize(device)
    start = time.perf_counter()
    value = float("nan")
    for i in range(args.steps):
        value = step(args.warmup + i)
    s3_torch.synchronize(device)
    ms = (time.perf_counter() - start) * 1e3 / args.steps
    out = {"framework": "torch", "device": str(device), "precision": args.precision, "ms_per_step": round(ms, 1),
           "peak_rss_mib": round(rss_mib("VmHWM"), 1), "rss_before_steps_mib": round(before, 1), "loss": value,
           "torch_version": torch.__version__}
    if device.type == "cuda":
        out["peak_gpu_mib"] = round(torch.cuda.max_memory_allocated(device) / 2**20, 1)
        out["gpu"] = torch.cuda.get_device_name(device)
    print(json.dumps(out))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--network", choices=["raft-stereo", "igev"], default="raft-stereo")
    parser.add_argument("--official", type=Path, required=True,
                        help="checkout of princeton-vl/RAFT-Stereo, or the IGEV-Stereo folder of gangweiX/IGEV")
    parser.add_argument("--batch", type=int, default=2)
    parser.add_argument("--height", type=int, default=384)
    parser.add_argument("--width", type=int, default=512)
    parser.add_argument("--hidden-dim", type=int, default=128)
    parser.add_argument("--gru-levels", type=int, default=3)
    parser.add_argument("--n-downsample", type=int, default=2)
    parser.add_argument("--train-iters", type=int, help="default: 16 (RAFT-Stereo), 22 (IGEV)")
    parser.add_argument("--test-iters", type=int, default=32)
    parser.add_argument("--steps", type=int, default=2)
    parser.add_argument("--warmup", type=int, default=1)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--seed", type=int, default=42)
    parser.add_argument("--no-build", metavar="EXE", help="use this step_time executable instead of building it")
    parser.add_argument("--device", default="cpu", help="cpu, cuda or cuda:N, for both frameworks")
    parser.add_argument("--precision", choices=["f32", "bf16", "f16"], default="f32")
    parser.add_argument("--torch-only", action="store_true", help="time the official PyTorch step alone")
    parser.add_argument("--torch-worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.train_iters is None:
        args.train_iters = 22 if args.network == "igev" else 16
    if args.torch_worker or args.torch_only:
        torch_worker(args)
        return
    exe = args.no_build or build_example()
    shape = ["--batch", str(args.batch), "--height", str(args.height), "--width", str(args.width),
             "--steps", str(args.steps), "--warmup", str(args.warmup), "--device", args.device,
             "--precision", args.precision]
    network = ["--hidden-dim", str(args.hidden_dim), "--gru-levels", str(args.gru_levels),
               "--n-downsample", str(args.n_downsample), "--train-iters", str(args.train_iters),
               "--test-iters", str(args.test_iters)]
    env = dict(os.environ, RAYON_NUM_THREADS=str(args.threads))
    burn, torch = [], []
    load_before = os.getloadavg()
    for _ in range(args.rounds):
        burn.append(run_json([exe, "--backbone", args.network] + shape + network, env))
        torch.append(run_json([sys.executable, __file__, "--torch-worker", "--network", args.network,
                               "--official", str(args.official),
                               "--threads", str(args.threads), "--seed", str(args.seed)] + shape + network, env))
    burn = min(burn, key=lambda r: r["ms_per_step"])
    torch = min(torch, key=lambda r: r["ms_per_step"])
    print(f"{args.threads} threads, torch {torch['torch_version']}, load average {load_before[0]:.2f} before / "
          f"{os.getloadavg()[0]:.2f} after; {args.network} hidden {args.hidden_dim}, {args.gru_levels} GRU levels, "
          f"{args.train_iters} train / {args.test_iters} test iterations\n")
    print("| batch, crop | burn-flex ms/step | PyTorch ms/step | burn / PyTorch | burn peak RSS MiB | "
          "PyTorch peak RSS MiB (before 1st step) |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    print(f"| {args.batch}, {args.height}x{args.width} | {burn['ms_per_step']:.0f} | {torch['ms_per_step']:.0f} "
          f"| {burn['ms_per_step'] / torch['ms_per_step']:.2f} | {burn['peak_rss_mib']:.0f} "
          f"| {torch['peak_rss_mib']:.0f} ({torch['rss_before_steps_mib']:.0f}) |")


if __name__ == "__main__":
    main()
