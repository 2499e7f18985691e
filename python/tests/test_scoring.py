"""`mbs.score` against `mbs-tool eval --gt`: on real Middlebury Teddy with the
built-in matcher's prediction, every protocol gives the command's JSON
(numbers within 1e-6) or refuses as the command does, with and without a
non-occluded mask and with the command's thresholds; wrong arguments are
`ValueError`s naming them.

`tools/test.sh` runs these with MBS_TOOL set to the `mbs-tool` binary of the
same tree.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import mbs

MBS_TOOL = os.environ.get("MBS_TOOL", "target/debug/mbs-tool")
TEDDY = Path(__file__).resolve().parents[2] / "testdata" / "middlebury-teddy"
PROTOCOLS = ["pixels", "s3", "raft-stereo", "igev-stereo", "kitti", "eth3d", "middlebury"]


def write_grey_png(path: Path, mask: np.ndarray[Any, np.dtype[np.uint8]]) -> None:
    """An 8-bit greyscale PNG, as `eval --noc` reads masks (mbs writes
    only RGB from Python)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    height, width = mask.shape
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    rows = b"".join(b"\x00" + mask[y].tobytes() for y in range(height))
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    path.write_bytes(png)


def regions(report: dict[str, Any]) -> dict[str, Any]:
    """The set's figures by region (`pooled` under pixels, `score` otherwise)."""
    figures: dict[str, Any] = report["pooled"] if report["protocol"] == "pixels" else report["score"]
    return figures


def agree(ours: Any, theirs: Any, where: str = "") -> None:
    """Equal JSON values, numbers within 1e-6."""
    if isinstance(theirs, dict):
        assert isinstance(ours, dict) and ours.keys() == theirs.keys(), where
        for key in theirs:
            agree(ours[key], theirs[key], f"{where}.{key}")
    elif isinstance(theirs, list):
        assert isinstance(ours, list) and len(ours) == len(theirs), where
        for i, (a, b) in enumerate(zip(ours, theirs)):
            agree(a, b, f"{where}[{i}]")
    elif isinstance(theirs, float) and not isinstance(ours, bool):
        assert ours == pytest.approx(theirs, abs=1e-6), where
    else:
        assert ours == theirs, where


@pytest.fixture(scope="module")
def teddy(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Teddy's quarter-size ground truth, the matcher's prediction and a
    mask, in memory and as the files `eval` reads."""
    root = tmp_path_factory.mktemp("teddy")
    codes = mbs.read_rgb(TEDDY / "disp2.png")[:, :, 0].astype(np.float32)
    gt = np.where(codes > 0, codes / 4.0, np.inf).astype(np.float32)
    left, right = mbs.read_rgb(TEDDY / "im2.png"), mbs.read_rgb(TEDDY / "im6.png")
    prediction = mbs.match_stereo(left, right, max_disparity=64)
    columns = np.arange(gt.shape[1])[None, :]
    noc = np.where(np.isfinite(gt) & (columns >= 40), 255, 0).astype(np.uint8)
    mbs.write_pfm(root / "gt.pfm", gt)
    mbs.write_pfm(root / "teddy.pfm", prediction)
    write_grey_png(root / "noc.png", noc)
    return {"root": root, "gt": gt, "prediction": prediction, "noc": noc}


def eval_json(teddy: dict[str, Any], *flags: str) -> tuple[dict[str, Any] | None, str]:
    """`eval teddy.pfm --gt gt.pfm FLAGS --json`: its report, or its error."""
    root = teddy["root"]
    args = [MBS_TOOL, "eval", root / "teddy.pfm", "--gt", root / "gt.pfm", *flags, "--json"]
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if done.returncode != 0:
        return None, done.stderr
    report: dict[str, Any] = json.loads(done.stdout)
    return report, done.stderr


@pytest.mark.parametrize("protocol", PROTOCOLS)
@pytest.mark.parametrize("masked", [False, True])
def test_every_protocol_scores_as_eval_or_refuses_as_it(teddy: dict[str, Any], protocol: str, masked: bool) -> None:
    flags = ["--protocol", protocol] + (["--noc", str(teddy["root"] / "noc.png")] if masked else [])
    theirs, stderr = eval_json(teddy, *flags)
    noc = teddy["noc"] if masked else None
    if theirs is None:
        with pytest.raises(ValueError) as refused:
            mbs.score(teddy["prediction"], teddy["gt"], noc=noc, protocol=protocol, name="teddy.pfm")
        reason = str(refused.value).split(": ", 1)[1]
        assert reason in stderr, (reason, stderr)
        return
    ours = mbs.score(teddy["prediction"], teddy["gt"], noc=noc, protocol=protocol, name="teddy.pfm")
    agree(ours, theirs)
    assert ("NOC" in regions(ours)) == masked


@pytest.mark.parametrize("protocol", ["pixels", "s3"])
def test_thresholds_are_the_commands(teddy: dict[str, Any], protocol: str) -> None:
    theirs, stderr = eval_json(teddy, "--protocol", protocol, "--thresholds", "0.5,4")
    assert theirs is not None, stderr
    ours = mbs.score(teddy["prediction"], teddy["gt"], protocol=protocol, thresholds=[0.5, 4.0], name="teddy.pfm")
    agree(ours, theirs)
    assert "out4" in regions(ours)["ALL"] and "out3" not in regions(ours)["ALL"]


def test_the_default_is_the_s3_papers_protocol(teddy: dict[str, Any]) -> None:
    report = mbs.score(teddy["prediction"], teddy["gt"])
    assert report["protocol"] == "s3"
    assert 0.0 < report["score"]["ALL"]["epe"] < 10.0


def test_wrong_arguments_are_named(teddy: dict[str, Any]) -> None:
    prediction, gt = teddy["prediction"], teddy["gt"]
    with pytest.raises(ValueError, match="^protocol: `evaldisp` is not a protocol"):
        mbs.score(prediction, gt, protocol="evaldisp")
    with pytest.raises(ValueError, match="^dataset: `kitti` is not a dataset"):
        mbs.score(prediction, gt, dataset="kitti")
    with pytest.raises(ValueError, match="^noc: expected a uint8 HxW array"):
        mbs.score(prediction, gt, noc=teddy["noc"].astype(np.float32))
    with pytest.raises(ValueError, match="^thresholds: -1"):
        mbs.score(prediction, gt, thresholds=[-1.0])
    with pytest.raises(ValueError, match="^gt: the ground truth has no valid pixel"):
        mbs.score(prediction, np.full_like(gt, np.inf))
    with pytest.raises(ValueError, match="prediction"):
        mbs.score(prediction[:, :-8].copy(), gt)


@pytest.fixture(scope="module")
def middlebury(teddy: dict[str, Any], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """MiddEval3 `trainingH` with two Teddy scenes (one with calib.txt's
    ndisp) and a folder of predictions for them."""
    root = tmp_path_factory.mktemp("middlebury")
    folder = root / "MiddEval3" / "trainingH"
    predictions = root / "pred"
    predictions.mkdir()
    gt = teddy["gt"]
    columns = np.arange(gt.shape[1])[None, :]
    mask = np.where(np.isfinite(gt), np.where(columns < 100, 128, 255), 0).astype(np.uint8)
    noisy = teddy["prediction"] + np.float32(0.7) * np.sin(columns).astype(np.float32)
    for scene, prediction in [("Teddy", teddy["prediction"]), ("TeddyB", noisy.astype(np.float32))]:
        (folder / scene).mkdir(parents=True)
        for view, name in [("im2.png", "im0.png"), ("im6.png", "im1.png")]:
            (folder / scene / name).write_bytes((TEDDY / view).read_bytes())
        mbs.write_pfm(folder / scene / "disp0GT.pfm", gt)
        write_grey_png(folder / scene / "mask0nocc.png", mask)
        mbs.write_pfm(predictions / f"{scene}.pfm", prediction)
    (folder / "Teddy" / "calib.txt").write_text("cam0=[375 0 100; 0 375 90; 0 0 1]\nbaseline=160\nndisp=60\n")
    return {"folder": folder, "predictions": predictions, "root": root}


@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_a_benchmark_folder_scores_as_eval_or_refuses_as_it(middlebury: dict[str, Path], protocol: str) -> None:
    folder, predictions = middlebury["folder"], middlebury["predictions"]
    args = [MBS_TOOL, "eval", predictions, "--middlebury", folder, "--protocol", protocol, "--json"]
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if done.returncode != 0:
        with pytest.raises(ValueError) as refused:
            mbs.score_folder(predictions, "middlebury", folder, protocol=protocol)
        reason = str(refused.value).split(": ", 1)[1]
        assert reason in done.stderr, (reason, done.stderr)
        return
    ours = mbs.score_folder(predictions, "middlebury", folder, protocol=protocol)
    assert ours.pop("failed") == []
    agree(ours, json.loads(done.stdout))
    assert len(ours["images"]) == 2


def test_frames_keep_what_they_list(middlebury: dict[str, Path]) -> None:
    folder, predictions = middlebury["folder"], middlebury["predictions"]
    listed = middlebury["root"] / "frames.txt"
    listed.write_text("# one scene\nTeddyB\n")
    args = [MBS_TOOL, "eval", predictions, "--middlebury", folder, "--frames", listed, "--json"]
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    ours = mbs.score_folder(predictions, "middlebury", folder, protocol="pixels", frames=["TeddyB"])
    ours.pop("failed")
    agree(ours, json.loads(done.stdout))
    assert [image["name"] for image in ours["images"]] == ["TeddyB"]
    with pytest.raises(OSError, match="Teddy9"):
        mbs.score_folder(predictions, "middlebury", folder, frames=["Teddy9"])
    with pytest.raises(ValueError, match="^benchmark: `kitti2015` is not a benchmark"):
        mbs.score_folder(predictions, "kitti2015", folder)


def test_a_missing_prediction_is_failed_and_the_others_scored(middlebury: dict[str, Path]) -> None:
    partial = middlebury["root"] / "partial"
    partial.mkdir()
    (partial / "Teddy.pfm").write_bytes((middlebury["predictions"] / "Teddy.pfm").read_bytes())
    report = mbs.score_folder(partial, "middlebury", middlebury["folder"])
    assert [image["name"] for image in report["images"]] == ["Teddy"]
    assert [name for name, _ in report["failed"]] == ["TeddyB"]
    assert "no prediction TeddyB" in report["failed"][0][1]
