#!/usr/bin/env python3
"""ONNX inference through mbs (ort, Rust) against Python onnxruntime, in the
same run, on the same model and input size.

The model: a generated stereo-shaped conv net heavy enough for inference to
dominate (left and right concatenated, 3x3 convs 6->16, 3 x 16->16 with
ReLU, 16->1; fixed random weights), dynamic size, fed with the built-in
`igev` card (RGB 0..255, padded to a multiple of 32: 1242x375 -> 1248x384).

- mbs: the release example `onnx_bench`: `OnnxStereo::predict` on a
  1242x375 pair (pre-processing, inference, un-padding, validity mask), and
  the same model run bare on ready 1248x384 tensors; their difference is
  mbs's pre/post-processing per frame.
- Python: `InferenceSession.run` on ready 1x3x384x1248 float32 arrays.

Both use the same ONNX Runtime (1.31.1 from tools/setup-ort.sh, CPU) with
the same number of intra-op threads; they run in alternating rounds and the
fastest round's median counts (least disturbed by other load).

Needs numpy and `pip install onnx` (not part of CI). From the repository root:
    python3 tools/bench/onnx_vs_python.py --rounds 5
"""

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

ROOT = Path(__file__).resolve().parents[2]


def conv_model(path, width=16, layers=3):
    rng = np.random.default_rng(0)
    inits, nodes = [], [helper.make_node("Concat", ["left", "right"], ["x0"], axis=1)]
    channels = [6] + [width] * (layers + 1) + [1]
    for i, (cin, cout) in enumerate(zip(channels[:-1], channels[1:])):
        w = (rng.standard_normal((cout, cin, 3, 3)) / np.sqrt(9 * cin)).astype(np.float32)
        inits += [numpy_helper.from_array(w, f"w{i}"), numpy_helper.from_array(np.zeros(cout, np.float32), f"b{i}")]
        last = i == len(channels) - 2
        out = "disparity" if last else f"c{i}"
        nodes.append(helper.make_node("Conv", [f"x{i}", f"w{i}", f"b{i}"], [out], pads=[1, 1, 1, 1]))
        if not last:
            nodes.append(helper.make_node("Relu", [out], [f"x{i + 1}"]))
    shape = [1, 3, "H", "W"]
    graph = helper.make_graph(
        nodes,
        "bench_stereo",
        [helper.make_tensor_value_info(n, TensorProto.FLOAT, shape) for n in ("left", "right")],
        [helper.make_tensor_value_info("disparity", TensorProto.FLOAT, [1, 1, "H", "W"])],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.save(model, str(path))


def python_times(model, shape, repeats, threads):
    sys.path.insert(0, str(ROOT / ".ort"))
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = threads
    session = ort.InferenceSession(str(model), options, providers=["CPUExecutionProvider"])
    feed = {"left": np.full(shape, 0.5, np.float32), "right": np.full(shape, 0.5, np.float32)}
    session.run(None, feed)  # warm-up
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        session.run(None, feed)
        times.append((time.perf_counter() - start) * 1e3)
    return float(np.median(times))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=10, help="frames per round")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--width", type=int, default=1242)
    parser.add_argument("--height", type=int, default=375)
    args = parser.parse_args()

    lib = subprocess.run(["bash", "tools/setup-ort.sh"], cwd=ROOT, check=True, capture_output=True, text=True)
    lib = lib.stdout.strip().splitlines()[-1]
    subprocess.run(["cargo", "build", "--release", "-p", "mbs-infer", "--example", "onnx_bench"], cwd=ROOT, check=True)
    exe = ROOT / "target/release/examples/onnx_bench"
    with tempfile.TemporaryDirectory() as tmp:
        model = Path(tmp) / "bench_stereo.onnx"
        conv_model(model)
        pad = lambda n: -(-n // 32) * 32
        shape = (1, 3, pad(args.height), pad(args.width))
        mbs_rounds, py_rounds = [], []
        for _ in range(args.rounds):
            out = subprocess.run(
                [exe, model, "igev", str(args.width), str(args.height), str(args.repeats), str(args.threads)],
                cwd=ROOT, check=True, capture_output=True, text=True, env={"ORT_DYLIB_PATH": lib},
            )
            mbs_rounds.append(json.loads(out.stdout))
            py_rounds.append(python_times(model, shape, args.repeats, args.threads))
    best = min(mbs_rounds, key=lambda r: r["full_ms"])
    full = best["full_ms"]
    infer = min(r["infer_ms"] for r in mbs_rounds)
    python = min(py_rounds)
    print(f"model: 5 3x3 convs (6-16-16-16-16-1), input {args.width}x{args.height} padded to {shape[3]}x{shape[2]}, "
          f"{args.threads} threads, {args.rounds} rounds x {args.repeats} frames, median per frame, best round")
    print(f"| | ms / frame |")
    print(f"| --- | ---: |")
    print(f"| Python onnxruntime, session.run | {python:.1f} |")
    print(f"| mbs, bare model run (ort) | {infer:.1f} |")
    print(f"| mbs, OnnxStereo::predict (pre + run + post) | {full:.1f} |")
    print(f"| mbs pre/post-processing (predict - bare run) | {full - infer:.1f} |")
    print(f"ratio mbs predict / Python run: {full / python:.3f}  (bare run: {infer / python:.3f})")


if __name__ == "__main__":
    main()
