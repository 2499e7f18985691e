#!/usr/bin/env python3
"""What bounds mbs-conv's 3x3 layers against PyTorch (issue 29): the matrix
product of one unfolded block, alone, and the whole layer's forward pass,
in mbs-conv (its release example `product_rate`, gemm 0.19) and in PyTorch
(`torch.mm` on the same product, `torch.nn.Conv2d` on the layer), on 1 and
on 2 threads, each framework in its own process.

    .venv-test/bin/python tools/bench/products_vs_torch.py --rounds 15

Prints a Markdown table: milliseconds (median of the rounds after one
warm-up) and GFLOP/s per case.
"""
import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from conv_layers_vs_torch import median_ms

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "target" / "release" / "examples" / "product_rate"


def torch_cases(rounds):
    """The same cases as `product_rate`, in PyTorch, in this process."""
    import torch

    results = []
    with torch.no_grad():
        for name, channels, (height, width) in [("3x3 64->64 @192x256", 64, (192, 256)),
                                                 ("3x3 128->128 @48x64", 128, (48, 64))]:
            k = channels * 9
            rows = max(1, (1 << 18) // (k * width))  # mbs-conv's PART_BUDGET
            weight, block = torch.rand(channels, k), torch.rand(k, rows * width)
            out = torch.empty(channels, rows * width)
            ms = median_ms(lambda: torch.mm(weight, block, out=out), rounds)
            flops = 2 * channels * k * rows * width
            results.append({"name": f"product of one block of {name}", "ms": ms, "gflops": flops / ms / 1e6})
            conv = torch.nn.Conv2d(channels, channels, 3, padding=1, bias=False)
            x = torch.rand(1, channels, height, width)
            ms = median_ms(lambda: conv(x), rounds)
            flops = 2 * channels * k * height * width
            results.append({"name": f"layer {name}", "ms": ms, "gflops": flops / ms / 1e6})
    return results


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--torch-threads", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.torch_threads:
        import torch
        torch.set_num_threads(args.torch_threads)
        print(json.dumps(torch_cases(args.rounds)))
        return
    try:
        import torch  # noqa: F401
    except ImportError:
        sys.exit("this benchmark needs PyTorch: pip install torch (not part of CI)")
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "mbs-conv", "--example", "product_rate"],
                   cwd=ROOT, check=True)
    print("| case | threads | mbs-conv ms (GFLOP/s) | PyTorch ms (GFLOP/s) | mbs / PyTorch |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for threads in (1, 2):
        env = dict(os.environ, RAYON_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads))
        ours = subprocess.run([str(EXAMPLE), str(args.rounds)], env=env, check=True,
                              capture_output=True, text=True).stdout
        ours = [json.loads(line) for line in ours.splitlines()]
        theirs = subprocess.run([sys.executable, __file__, "--rounds", str(args.rounds),
                                 "--torch-threads", str(threads)], env=env, check=True,
                                capture_output=True, text=True).stdout
        theirs = {case["name"]: case for case in json.loads(theirs)}
        for case in ours:
            peer = theirs[case["name"]]
            print(f"| {case['name']} | {threads} | {case['ms']:.3f} ({case['gflops']:.0f}) | "
                  f"{peer['ms']:.3f} ({peer['gflops']:.0f}) | {case['ms'] / peer['ms']:.2f} |")


if __name__ == "__main__":
    main()
