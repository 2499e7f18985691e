#!/usr/bin/env python3
"""Time per pair of a network exported by `mbs-tool export --format onnx`
through ONNX Runtime (`predict --model NAME.onnx --card NAME.card.json`)
against mbs's own forward pass of the same weights (`predict --backbone X
--weights W`), on the CPU, in the same run, alternating (issue 58).

The networks are the official-size compact, RAFT-Stereo and IGEV-Stereo
(default settings, `--iters` iterations) with the weights of a two-step
training run on a small synthetic set (written as official-key
safetensors by `export`): no download. The pair is Middlebury's Teddy
(testdata, 450x375), exported at that size. Each timing is `predict`'s own
report for the pair ("1 done ... in S s"), which leaves out loading the
model; the median of --rounds runs.

    python3 tools/bench/onnx_export_vs_mbs.py --mbs-tool target/release/mbs-tool
"""

import argparse
import re
import statistics
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TEDDY = ROOT / "testdata" / "middlebury-teddy"


def tool(binary, *args):
    done = subprocess.run([binary, *map(str, args)], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(done.stdout + done.stderr)
    return done.stdout + done.stderr


def seconds(binary, out, *source):
    text = tool(binary, "predict", "--left", TEDDY / "im2.png", "--right", TEDDY / "im6.png", "--out", out, *source)
    found = re.search(r"predict: 1 done, 0 skipped, 0 failed in ([0-9.]+) s", text)
    if found is None:
        raise SystemExit(f"predict did not report its time: {text}")
    return float(found.group(1))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mbs-tool", default=str(ROOT / "target" / "release" / "mbs-tool"))
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--iters", type=int, default=12)
    args = parser.parse_args()
    binary = args.mbs_tool
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        tool(binary, "synth", "--out", tmp / "data", "--frames", "1", "--towns", "Town01,Town10",
             "--weathers", "ClearNoon", "--width", "128", "--height", "64", "--focal", "64", "--no-checksums")
        print(f"| network ({args.iters} iterations), Teddy 450x375, CPU | mbs forward (s) | ONNX Runtime (s) | ONNX / mbs |")
        print("| --- | ---: | ---: | ---: |")
        for backbone in ["compact", "raft-stereo", "igev"]:
            run = tmp / f"run-{backbone}"
            tool(binary, "train", tmp / "data" / "manifest.json", "--out", run, "--backbone", backbone,
                 "--steps", "2", "--batch-size", "1", "--crop", "64x128", "--val-every", "2",
                 "--set", "data.val_samples=1")
            weights = tmp / f"{backbone}.safetensors"
            tool(binary, "export", run, "--out", weights)
            model = tmp / f"{backbone}.onnx"
            iters = [] if backbone == "compact" else ["--iters", args.iters]
            tool(binary, "export", "--backbone", backbone, "--weights", weights, "--out", model,
                 "--size", "375x450", *iters)
            card = tmp / f"{backbone}.card.json"
            setting = [] if backbone == "compact" else [
                "--set", f"network.{backbone.replace('-', '_')}.test_iters={args.iters}"]
            ours, theirs = [], []
            for r in range(args.rounds):
                ours.append(seconds(binary, tmp / f"p-{backbone}-{r}", "--backbone", backbone, "--weights", weights, *setting))
                theirs.append(seconds(binary, tmp / f"q-{backbone}-{r}", "--model", model, "--card", card))
            m, o = statistics.median(ours), statistics.median(theirs)
            print(f"| {backbone} | {m:.3f} | {o:.3f} | {o / m:.2f} |", flush=True)


if __name__ == "__main__":
    main()
