#!/usr/bin/env python3
"""The networks' convolutions one layer at a time: mbs's (mbs-conv's
kernels, as the networks run them) and burn's flex CPU backend alone (the
release example `conv_layers`, crates/mbs-nets/examples, with and without
--burn) against PyTorch on the CPU, same shapes, batch 1, f32, 2 threads
each, each in its own process (issue 29).

Three timings per layer, each the median of --rounds after one warm-up:
the forward pass alone (PyTorch under no_grad), forward + backward for the
weight gradient only (the input does not require one), and forward +
backward for the input's and the weight's gradients. The input gradient's
share is the difference of the last two.

Needs PyTorch (`pip install torch`; not part of CI). From the repository
root:

    python3 tools/bench/conv_layers_vs_torch.py --rounds 5
"""

import argparse
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
THREADS = 2


def median_ms(run, rounds):
    """Median milliseconds of `rounds` calls of `run` after one warm-up."""
    run()
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        run()
        times.append((time.perf_counter() - start) * 1e3)
    return sorted(times)[len(times) // 2]


def rust_layers(rounds, *flags):
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "mbs-nets", "--example", "conv_layers"],
                   cwd=ROOT, check=True)
    env = {**os.environ, "RAYON_NUM_THREADS": str(THREADS)}
    out = subprocess.run([ROOT / "target/release/examples/conv_layers", str(rounds), *flags], env=env,
                         check=True, stdout=subprocess.PIPE, text=True).stdout
    return [json.loads(line) for line in out.splitlines()]


def shape_of(name):
    """Channels, kernel, stride, groups and input size from the example's layer name."""
    kernel = re.match(r"(?:depthwise )?(\d+)x\d+(?:x\d+)?(?:/(\d+))?", name)
    size = [int(v) for v in re.search(r"@([\dx]+)", name).group(1).split("x")]
    channels = re.search(r"(\d+)->(\d+)", name)
    if channels:
        cin, cout, groups = int(channels.group(1)), int(channels.group(2)), 1
    else:
        cin = cout = groups = int(re.search(r"(\d+) ch", name).group(1))
    return cin, cout, int(kernel.group(1)), int(kernel.group(2) or 1), groups, size


def torch_layer(name, rounds):
    import torch

    cin, cout, k, stride, groups, size = shape_of(name)
    conv_type = torch.nn.Conv3d if len(size) == 3 else torch.nn.Conv2d
    conv = conv_type(cin, cout, k, stride=stride, padding=k // 2, groups=groups)

    x = torch.rand(1, cin, *size)
    with torch.no_grad():
        forward = median_ms(lambda: conv(x), rounds)

    def grads(input_grad):
        inp = x.clone().requires_grad_(input_grad)

        def run():
            conv.zero_grad(set_to_none=True)
            conv(inp).sum().backward()
        return median_ms(run, rounds)

    return {"name": name, "forward_ms": forward, "weight_grad_ms": grads(False), "both_grads_ms": grads(True)}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--torch-only", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--names", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.torch_only:
        import torch

        torch.set_num_threads(THREADS)
        for name in json.loads(args.names):
            print(json.dumps(torch_layer(name, args.rounds)), flush=True)
        return
    try:
        import torch
    except ImportError:
        sys.exit("this benchmark needs PyTorch: pip install torch (not part of CI)")
    load_before = os.getloadavg()[0]
    ours = rust_layers(args.rounds)
    burn = {layer["name"]: layer for layer in rust_layers(args.rounds, "--burn")}
    names = json.dumps([layer["name"] for layer in ours])
    out = subprocess.run([sys.executable, __file__, "--torch-only", "--rounds", str(args.rounds), "--names", names],
                         check=True, stdout=subprocess.PIPE, text=True).stdout
    theirs = {layer["name"]: layer for layer in map(json.loads, out.splitlines())}
    print(f"torch {torch.__version__}, {THREADS} threads each, median of {args.rounds}, "
          f"load average {load_before:.2f} before / {os.getloadavg()[0]:.2f} after\n")
    print("| layer | forward mbs / flex / torch (ms) | mbs / torch | weight grad mbs / flex / torch (ms) "
          "| mbs / torch | both grads mbs / flex / torch (ms) | mbs / torch |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for layer in ours:
        peer, flex = theirs[layer["name"]], burn[layer["name"]]
        cells = []
        for key in ("forward_ms", "weight_grad_ms", "both_grads_ms"):
            cells += [f"{layer[key]:.1f} / {flex[key]:.1f} / {peer[key]:.1f}", f"{layer[key] / peer[key]:.2f}"]
        print(f"| {layer['name']} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
