#!/usr/bin/env python3
"""S3 training step of mbs-train (burn, flex CPU backend) against the same
step in PyTorch on the CPU, in the same run, on the same configurations.

- burn: the release example `step_time` (crates/mbs-train/examples/
  step_time.rs): `S3Trainer::step` of a `CostVolumeNet` (16 feature, 32
  hidden channels), RAYON_NUM_THREADS=THREADS;
- PyTorch: tools/bench/s3_torch.py, an op-for-op port of the network and of
  the step (teacher forward, student forward with mirroring, full S3 loss,
  backward, global-norm clipping, Adam, EMA), torch.set_num_threads(THREADS).

Both take random images with a fixed seed, WARMUP untimed steps, then STEPS
timed steps; each runs in its own process (peak RSS is that process's
VmHWM, PyTorch's includes the ~0.7 GB of the imported library, also shown
alone). Rounds alternate burn and PyTorch; the fastest round of each
counts. Configurations: batch 2 at 256x512 with 128 px (the finetuning crop
of docs/conventions.md §5) and batch 4 at 64x128 with 32 px.

`--precision bf16|f16` runs both in mixed precision: mbs's
`trainer.precision`, and PyTorch's autocast (f16 with a GradScaler).

Needs PyTorch (`pip install torch`; not part of CI or tools/test.sh). From
the repository root:
    python3 tools/bench/train_step_vs_torch.py --rounds 3
    python3 tools/bench/train_step_vs_torch.py --rounds 1 --precision bf16
"""

import argparse
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TORCH_STEP = Path(__file__).resolve().parent / "s3_torch.py"
# (batch, height, width, max disparity, timed steps, warm-up steps)
CONFIGS = [(2, 256, 512, 128, 10, 3), (4, 64, 128, 32, 30, 5)]
# Keeps freed memory in the heap instead of returning it to the kernel, so
# large tensors do not page-fault in afresh at every op (--glibc-tunables).
TUNABLES = "glibc.malloc.mmap_threshold=4294967296:glibc.malloc.trim_threshold=68719476736"


def build_example():
    """Builds the release example and returns its path (from cargo's own report)."""
    command = ["cargo", "build", "--release", "-p", "mbs-train", "--example", "step_time",
               "--message-format=json-render-diagnostics"]
    out = subprocess.run(command, cwd=ROOT, check=True, stdout=subprocess.PIPE, text=True)
    for line in out.stdout.splitlines():
        message = json.loads(line)
        if message.get("reason") == "compiler-artifact" and message["target"]["name"] == "step_time":
            if message.get("executable"):
                return message["executable"]
    sys.exit("cargo built no step_time executable")


def run_json(command, env):
    out = subprocess.run(command, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if out.returncode != 0:
        sys.exit(f"{' '.join(map(str, command))} failed:\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def config_args(batch, height, width, disparity, steps, warmup):
    return ["--batch", str(batch), "--height", str(height), "--width", str(width),
            "--max-disparity", str(disparity), "--steps", str(steps), "--warmup", str(warmup)]


def measure(exe, config, threads, rounds, tunables, breakdown=False, precision="f32"):
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    if tunables:
        env["GLIBC_TUNABLES"] = TUNABLES
    args = config_args(*config) + (["--breakdown"] if breakdown else []) + ["--precision", precision]
    burn, torch = [], []
    for _ in range(rounds):
        burn.append(run_json([exe] + args, env))
        torch.append(run_json([sys.executable, str(TORCH_STEP), "--threads", str(threads)] + args, env))
    fastest = lambda results: min(results, key=lambda r: r["ms_per_step"])
    return fastest(burn), fastest(torch)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=3, help="alternating runs of each framework per configuration")
    parser.add_argument("--threads", type=int, default=2, help="RAYON_NUM_THREADS and torch.set_num_threads")
    parser.add_argument("--steps", type=int, help="timed steps (default 10 at 256x512, 30 at 64x128)")
    parser.add_argument("--warmup", type=int, help="untimed steps first (default 3 at 256x512, 5 at 64x128)")
    parser.add_argument("--breakdown", action="store_true", help="also time the phases of the step (one more round)")
    parser.add_argument("--glibc-tunables", action="store_true",
                        help="also run both with GLIBC_TUNABLES keeping freed memory in the heap")
    parser.add_argument("--no-build", metavar="EXE", help="use this step_time executable instead of building it")
    parser.add_argument("--precision", choices=["f32", "bf16", "f16"], default="f32",
                        help="mixed precision in both (trainer.precision; torch.autocast)")
    args = parser.parse_args()
    if importlib.util.find_spec("torch") is None:
        sys.exit("PyTorch is not installed; this benchmark needs it: pip install torch "
                 "(the CPU build is enough; it is not part of CI)")
    exe = args.no_build or build_example()
    configs = [(b, h, w, d, args.steps or s, args.warmup if args.warmup is not None else k)
               for b, h, w, d, s, k in CONFIGS]
    load_before = os.getloadavg()
    rows, breakdowns = [], []
    variants = [False, True] if args.glibc_tunables else [False]
    for tunables in variants:
        for config in configs:
            burn, torch = measure(exe, config, args.threads, args.rounds, tunables, precision=args.precision)
            rows.append((config, tunables, burn, torch))
    if args.breakdown:
        for config in configs:
            breakdowns.append((config, *measure(exe, config, args.threads, 1, False, breakdown=True)))
    load_after = os.getloadavg()

    torch_version = rows[0][3].get("torch_version", "?")
    print(f"{args.precision}, {args.threads} threads, {args.rounds} rounds (fastest counts), torch {torch_version}, "
          f"load average {load_before[0]:.2f} before / {load_after[0]:.2f} after\n")
    print("| batch, crop, max disparity | malloc | burn-flex ms/step | PyTorch ms/step | burn / PyTorch "
          "| burn peak RSS MiB | PyTorch peak RSS MiB (before 1st step) |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
    for (batch, height, width, disparity, steps, warmup), tunables, burn, torch in rows:
        malloc = "tunables" if tunables else "default"
        print(f"| {batch}, {height}x{width}, {disparity} px ({steps} steps) | {malloc} | {burn['ms_per_step']:.1f} "
              f"| {torch['ms_per_step']:.1f} | {burn['ms_per_step'] / torch['ms_per_step']:.2f} "
              f"| {burn['peak_rss_mib']:.0f} | {torch['peak_rss_mib']:.0f} ({torch['rss_before_steps_mib']:.0f}) |")
    if breakdowns:
        phases = list(breakdowns[0][1]["breakdown_ms"])
        print("\nPhases of the step, ms (one run of each, default malloc):\n")
        print("| batch, crop | framework | " + " | ".join(phases) + " |")
        print("| --- | --- |" + " ---: |" * len(phases))
        for (batch, height, width, disparity, _, _), burn, torch in breakdowns:
            for name, result in (("burn-flex", burn), ("PyTorch", torch)):
                cells = " | ".join(f"{result['breakdown_ms'][p]:.1f}" for p in phases)
                print(f"| {batch}, {height}x{width}, {disparity} px | {name} | {cells} |")


if __name__ == "__main__":
    main()
