#!/usr/bin/env python3
"""Generates the small ONNX test models of testdata/onnx/.

Each model's output is an exact, known function of its inputs, so the Rust
tests can check mbs's pre- and post-processing (padding, mirroring, sign,
resizing, mask conventions) against real ONNX Runtime:

- stereo_dynamic.onnx  inputs left, right (N x 3 x H x W float, any N, H, W
  multiple of 8: a SpaceToDepth/DepthToSpace pair fails otherwise); output
  disparity (N x 1 x H x W) = 0.5 * mean_c left[y, x] + 0.25 * mean_c
  right[y, x + 1] + 1, with right[y, W] = 0 (zero padding of the conv).
- stereo_negative.onnx the same, output flow = minus that (RAFT-Stereo style).
- stereo_fixed.onnx    the same function on a fixed 1 x 3 x 32 x 48 input.
- inpaint_lama.onnx    LaMa style, fixed 64 x 64: image (1 x 3 float in 0..1),
  mask (1 x 1 float, 1 = hole); output = (image * (1 - mask) + 0.5 * mask) * 255.
- inpaint_migan.onnx   MI-GAN style, any size, uint8: image (1 x 3), mask
  (1 x 1, 255 = keep, 0 = hole); result = image where kept, 77 in holes.
- depth_metric.onnx    monocular depth, any size: image (1 x 3 float) -> depth
  (1 x 1) = 1 + mean_c image (positive: fits a metric-depth card).
- depth_negative.onnx  the same, depth = mean_c image - 0.5 (zero or negative
  values a card claiming metric depth must refuse).
- depth_nan.onnx       depth = sqrt(mean_c image - 2): NaN everywhere for
  inputs in 0..1.
- depth_half.onnx      depth = 1 + mean_c image, average-pooled to half the
  size: an output that does not fit its card.

Usage: python3 tools/onnx/make_test_models.py [OUT_DIR]  (needs `pip install onnx`)
"""
import sys
from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

OPSET = 17
IR_VERSION = 8  # read by every ONNX Runtime since 1.10


def save(graph, path):
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)])
    model.ir_version = IR_VERSION
    model.producer_name = "mbs tools/onnx/make_test_models.py"
    onnx.checker.check_model(model)
    onnx.save(model, str(path))


def stereo_graph(name, shape, output, negate):
    """left, right -> 0.5 mean(left) + 0.25 mean(right shifted left by 1) + 1."""
    weights = np.zeros((1, 6, 1, 2), np.float32)
    weights[0, :3, 0, 0] = 0.5 / 3
    weights[0, 3:, 0, 1] = 0.25 / 3
    nodes = [
        helper.make_node("Concat", ["left", "right"], ["pair"], axis=1),
        helper.make_node("Conv", ["pair", "w", "b"], ["d"], pads=[0, 0, 0, 1]),
        # Identity that only accepts sides that are multiples of 8.
        helper.make_node("SpaceToDepth", ["d"], ["blocks"], blocksize=8),
        helper.make_node("DepthToSpace", ["blocks"], ["out" if negate else output], blocksize=8),
    ]
    if negate:
        nodes.append(helper.make_node("Neg", ["out"], [output]))
    n, _, h, w = shape
    return helper.make_graph(
        nodes,
        name,
        [
            helper.make_tensor_value_info("left", TensorProto.FLOAT, shape),
            helper.make_tensor_value_info("right", TensorProto.FLOAT, shape),
        ],
        [helper.make_tensor_value_info(output, TensorProto.FLOAT, [n, 1, h, w])],
        [numpy_helper.from_array(weights, "w"), numpy_helper.from_array(np.ones(1, np.float32), "b")],
    )


def lama_graph():
    size = [1, 3, 64, 64]
    nodes = [
        helper.make_node("Sub", ["one", "mask"], ["keep"]),
        helper.make_node("Mul", ["image", "keep"], ["kept"]),
        helper.make_node("Mul", ["mask", "half"], ["filled"]),
        helper.make_node("Add", ["kept", "filled"], ["unit"]),
        helper.make_node("Mul", ["unit", "full"], ["output"]),
    ]
    consts = [
        numpy_helper.from_array(np.array(1.0, np.float32), "one"),
        numpy_helper.from_array(np.array(0.5, np.float32), "half"),
        numpy_helper.from_array(np.array(255.0, np.float32), "full"),
    ]
    return helper.make_graph(
        nodes,
        "lama_like",
        [
            helper.make_tensor_value_info("image", TensorProto.FLOAT, size),
            helper.make_tensor_value_info("mask", TensorProto.FLOAT, [1, 1, 64, 64]),
        ],
        [helper.make_tensor_value_info("output", TensorProto.FLOAT, size)],
        consts,
    )


def migan_graph():
    nodes = [
        helper.make_node("Cast", ["image"], ["image_f"], to=TensorProto.FLOAT),
        helper.make_node("Cast", ["mask"], ["mask_f"], to=TensorProto.FLOAT),
        helper.make_node("Div", ["mask_f", "full"], ["keep"]),
        helper.make_node("Sub", ["one", "keep"], ["hole"]),
        helper.make_node("Mul", ["image_f", "keep"], ["kept"]),
        helper.make_node("Mul", ["hole", "fill"], ["filled"]),
        helper.make_node("Add", ["kept", "filled"], ["sum"]),
        helper.make_node("Cast", ["sum"], ["result"], to=TensorProto.UINT8),
    ]
    consts = [
        numpy_helper.from_array(np.array(1.0, np.float32), "one"),
        numpy_helper.from_array(np.array(255.0, np.float32), "full"),
        numpy_helper.from_array(np.array(77.0, np.float32), "fill"),
    ]
    return helper.make_graph(
        nodes,
        "migan_like",
        [
            helper.make_tensor_value_info("image", TensorProto.UINT8, [1, 3, "H", "W"]),
            helper.make_tensor_value_info("mask", TensorProto.UINT8, [1, 1, "H", "W"]),
        ],
        [helper.make_tensor_value_info("result", TensorProto.UINT8, [1, 3, "H", "W"])],
        consts,
    )


def depth_graph(name, tail):
    """image -> mean over channels, then the nodes of `tail` -> depth."""
    nodes = [helper.make_node("ReduceMean", ["image"], ["mean"], axes=[1], keepdims=1)]
    consts = {
        "one": 1.0,
        "half": 0.5,
        "two": 2.0,
    }
    nodes += tail
    return helper.make_graph(
        nodes,
        name,
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, "H", "W"])],
        [helper.make_tensor_value_info("depth", TensorProto.FLOAT, [1, 1, None, None])],
        [numpy_helper.from_array(np.array(v, np.float32), k) for k, v in consts.items()],
    )


def depth_models():
    """The depth test models: name -> graph."""
    plus_one = helper.make_node("Add", ["mean", "one"], ["depth"])
    return {
        "depth_metric": depth_graph("depth_metric", [plus_one]),
        "depth_negative": depth_graph(
            "depth_negative", [helper.make_node("Sub", ["mean", "half"], ["depth"])]
        ),
        "depth_nan": depth_graph(
            "depth_nan",
            [
                helper.make_node("Sub", ["mean", "two"], ["below"]),
                helper.make_node("Sqrt", ["below"], ["depth"]),
            ],
        ),
        "depth_half": depth_graph(
            "depth_half",
            [
                helper.make_node("Add", ["mean", "one"], ["full"]),
                helper.make_node("AveragePool", ["full"], ["depth"], kernel_shape=[2, 2], strides=[2, 2]),
            ],
        ),
    }


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "testdata/onnx"
    out.mkdir(parents=True, exist_ok=True)
    dynamic = ["N", 3, "H", "W"]
    save(stereo_graph("stereo_dynamic", dynamic, "disparity", False), out / "stereo_dynamic.onnx")
    save(stereo_graph("stereo_negative", dynamic, "flow", True), out / "stereo_negative.onnx")
    save(stereo_graph("stereo_fixed", [1, 3, 32, 48], "disparity", False), out / "stereo_fixed.onnx")
    save(lama_graph(), out / "inpaint_lama.onnx")
    save(migan_graph(), out / "inpaint_migan.onnx")
    for name, graph in depth_models().items():
        save(graph, out / f"{name}.onnx")
    print(f"wrote 9 models to {out}")


if __name__ == "__main__":
    main()
