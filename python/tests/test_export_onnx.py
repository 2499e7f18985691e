"""`mbs-tool export --format onnx` writes models the official ONNX checker
accepts (with its full check: types and shapes inferred through every node)
for the compact network, RAFT-Stereo and IGEV-Stereo, at every opset the
command offers.

`tools/test.sh` runs these with MBS_TOOL set to the `mbs-tool` binary of
the same tree.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import onnx
import pytest

MBS_TOOL = os.environ.get("MBS_TOOL", "target/debug/mbs-tool")

NETWORKS = {
    "compact": [],
    "raft-stereo": [
        "network.raft_stereo.hidden_dim=32",
        "network.raft_stereo.train_iters=2",
        "network.raft_stereo.test_iters=2",
    ],
    "igev": [
        "network.igev.hidden_dim=32",
        "network.igev.train_iters=2",
        "network.igev.test_iters=2",
        "network.igev.max_disp=64",
    ],
}


def mbs_tool(*args: object) -> subprocess.CompletedProcess[str]:
    """Runs mbs-tool and fails the test, with its output, when it fails."""
    done = subprocess.run([MBS_TOOL, *map(str, args)], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    return done


@pytest.fixture(scope="module")
def manifest(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small synthetic set made by `mbs-tool synth`."""
    root = tmp_path_factory.mktemp("synth")
    mbs_tool(
        "synth", "--out", root, "--frames", "1", "--towns", "Town01,Town10", "--weathers", "ClearNoon",
        "--width", "128", "--height", "64", "--focal", "64", "--no-checksums",
    )  # fmt: skip
    return root / "manifest.json"


@pytest.fixture(scope="module")
def runs(manifest: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A two-step training run of each backbone."""
    root = tmp_path_factory.mktemp("runs")
    made = {}
    for backbone, network in NETWORKS.items():
        settings = [arg for setting in network for arg in ("--set", setting)]
        made[backbone] = root / backbone
        mbs_tool(
            "train", manifest, "--out", made[backbone], "--backbone", backbone, "--steps", "2",
            "--batch-size", "1", "--crop", "64x128", "--max-disparity", "32", "--val-every", "2",
            "--set", "data.val_samples=1", *settings,
        )  # fmt: skip
    return made


@pytest.mark.parametrize("backbone", sorted(NETWORKS))
@pytest.mark.parametrize("opset", [16, 17, 18])
def test_the_onnx_checker_accepts_every_export(
    runs: dict[str, Path], tmp_path: Path, backbone: str, opset: int
) -> None:
    model = tmp_path / "net.onnx"
    mbs_tool("export", runs[backbone], "--out", model, "--size", "64x96", "--opset", opset)
    onnx.checker.check_model(str(model), full_check=True)
    loaded = onnx.load(str(model))
    assert loaded.opset_import[0].version == opset
    assert [i.name for i in loaded.graph.input] == ["left", "right"]
    assert [o.name for o in loaded.graph.output] == ["disparity"]
    shape = [d.dim_value for d in loaded.graph.output[0].type.tensor_type.shape.dim]
    assert shape == [1, 1, 64, 96]
    assert not any(node.op_type == "GridSample" for node in loaded.graph.node)
