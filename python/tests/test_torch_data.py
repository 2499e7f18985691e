"""`mbs.torch.MultiBaselineDataset` against the files and the trainer's
rules: each item's crops are the crops of its views read from disk, its
ratios the rig's baseline ratios, its sides those of its triplet, its
draws the paper's ranges; a step's batch is the same in any process and
under `DataLoader(num_workers=2)`, and differs between steps and seeds.
Bad arguments are `ValueError`s and a bad manifest an `OSError`, each
naming what is wrong.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

import mbs
from mbs.torch import MultiBaselineDataset, augment_batch

MBS_TOOL = os.environ.get("MBS_TOOL", "target/debug/mbs-tool")


def synth(root: Path, *args: str) -> Path:
    """A synthetic MBS20K-style set made by `mbs-tool synth`; its manifest."""
    done = subprocess.run(
        [MBS_TOOL, "synth", "--out", str(root), "--weathers", "ClearNoon", "--no-checksums", *args],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return root / "manifest.json"


@pytest.fixture(scope="module")
def manifest(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three small frames of one town."""
    return synth(
        tmp_path_factory.mktemp("synth"),
        "--seed",
        "5",
        "--frames",
        "3",
        "--towns",
        "Town01",
        "--width",
        "96",
        "--height",
        "48",
        "--focal",
        "48",
    )


def test_items_are_crops_of_their_views_with_the_rigs_ratios(manifest: Path) -> None:
    data = MultiBaselineDataset(manifest, steps=4, batch_size=3, crop=(32, 48), seed=11)
    parsed = mbs.load_manifest(manifest)
    samples = {s["id"]: s for s in parsed["samples"]}
    batch = data[2]
    assert batch["reference"].shape == (3, 3, 32, 48) and batch["reference"].dtype == torch.float32
    assert batch["occlusion"].shape == (3, 1, 32, 48)
    for item in range(3):
        sample = samples[batch["sample_ids"][item]]
        top, left = batch["windows"][item].tolist()
        reference, student, teacher = batch["triplets"][item].tolist()
        assert reference not in (student, teacher)
        for name, view in [("reference", reference), ("student_target", student), ("teacher_target", teacher)]:
            image = mbs.read_rgb(manifest.parent / sample["views"][view])
            crop = image[top : top + 32, left : left + 48].transpose(2, 0, 1).astype(np.float32) / 255.0
            np.testing.assert_array_equal(batch[name][item].numpy(), crop, err_msg=f"item {item} {name}")
        assert batch["student_sides"][item] == ("right" if student > reference else "left")
        assert batch["teacher_sides"][item] == ("right" if teacher > reference else "left")
        # Camera k sits at x = k B: r = |t_s - r| / |t_t - r| in views.
        expected = abs(student - reference) / abs(teacher - reference)
        assert batch["ratios"][item].item() == pytest.approx(expected, rel=1e-6)
    for factor in ["brightness", "contrast", "saturation"]:
        assert ((batch[factor] >= 0.6) & (batch[factor] <= 1.4)).all()
    reference, target = augment_batch(batch)
    assert ((reference >= 0) & (reference <= 1)).all() and reference.shape == batch["reference"].shape
    assert not torch.equal(target, batch["student_target"])


def test_a_steps_batch_depends_on_seed_and_step_only(manifest: Path) -> None:
    data = MultiBaselineDataset(manifest, steps=6, batch_size=2, crop=(32, 48), seed=3)
    again = MultiBaselineDataset(manifest, steps=6, batch_size=2, crop=(32, 48), seed=3)
    other_seed = MultiBaselineDataset(manifest, steps=6, batch_size=2, crop=(32, 48), seed=4)
    assert torch.equal(augment_batch(data[5])[1], augment_batch(again[5])[1])
    assert not torch.equal(data[4]["reference"], data[5]["reference"])
    assert not torch.equal(data[5]["reference"], other_seed[5]["reference"])
    # Workers started by "spawn" get the dataset pickled; it rebuilds its Rust side.
    copied = pickle.loads(pickle.dumps(data))
    assert torch.equal(copied[3]["reference"], data[3]["reference"])
    alone = [data[k] for k in range(6)]
    loaded = list(DataLoader(data, batch_size=None, num_workers=2))
    assert [b["step"] for b in loaded] == list(range(6))
    for a, b in zip(alone, loaded):
        for name in ["reference", "teacher_target", "occlusion", "brightness", "ratios", "triplets", "windows"]:
            assert torch.equal(a[name], b[name]), name


def test_bad_settings_and_manifests_are_named(manifest: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="batch_size"):
        MultiBaselineDataset(manifest, steps=1, batch_size=0)
    with pytest.raises(ValueError, match="crop"):
        MultiBaselineDataset(manifest, steps=1, crop=(8, 8))
    with pytest.raises(ValueError, match="crop"):
        MultiBaselineDataset(manifest, steps=1, crop="big")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="steps"):
        MultiBaselineDataset(manifest, steps=0)
    with pytest.raises(ValueError, match="augment"):
        MultiBaselineDataset(manifest, steps=1, crop=(32, 48), augment={"contrast": 3})
    with pytest.raises(ValueError, match="augment"):
        MultiBaselineDataset(manifest, steps=1, crop=(32, 48), augment={"contrast": "high"})
    with pytest.raises(OSError, match="smaller than the 64x128 crop"):
        MultiBaselineDataset(manifest, steps=1, crop=(64, 128))
    broken = tmp_path / "manifest.json"
    broken.write_text(json.dumps({"rig": "nope"}))
    with pytest.raises(OSError, match="manifest.json"):
        MultiBaselineDataset(broken, steps=1, crop=(32, 48))
    with pytest.raises(IndexError):
        MultiBaselineDataset(manifest, steps=2, crop=(32, 48))[2]


def test_the_example_trains_a_pytorch_network_with_s3(tmp_path: Path) -> None:
    """python/examples/s3_train.py from random weights on synth data (six
    frames of two towns, the test split held out): the held-out EPE of its
    teacher falls to at most 0.7x the untrained one's, and so does its
    held-out photometric error, to at most 0.85x (measured on this data
    with seeds 0, 1, 2: EPE 0.42x, 0.54x, 0.41x; photometric error 0.71x,
    0.77x, 0.70x)."""
    manifest = synth(
        tmp_path / "synth",
        "--seed",
        "13",
        "--frames",
        "6",
        "--towns",
        "Town01,Town10",
        "--width",
        "192",
        "--height",
        "96",
        "--focal",
        "96",
    )
    example = os.path.join(os.path.dirname(__file__), "..", "examples", "s3_train.py")
    log = tmp_path / "train.jsonl"
    done = subprocess.run(
        [
            sys.executable,
            example,
            str(manifest),
            "--steps",
            "200",
            "--batch-size",
            "4",
            "--crop",
            "64x160",
            "--lr",
            "3e-3",
            "--workers",
            "1",
            "--log",
            str(log),
        ],
        capture_output=True,
        text=True,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert done.returncode == 0, done.stdout + done.stderr
    lines = [json.loads(line) for line in log.read_text().splitlines()]
    scores = [line["eval"] for line in lines if "eval" in line]
    steps = [line for line in lines if "loss" in line]
    assert len(steps) == 200 and [s["step"] for s in scores] == [0, 200]
    assert all(np.isfinite(s["loss"]) for s in steps)
    assert scores[1]["epe"] <= 0.7 * scores[0]["epe"], scores
    assert scores[1]["photometric"] <= 0.85 * scores[0]["photometric"], scores


def test_the_readme_training_loop_runs(manifest: Path) -> None:
    """The README's twenty-line loop, as written, with the example's
    network for `MyStereoNet` and three steps, runs to a finite loss."""
    readme = open(os.path.join(os.path.dirname(__file__), "..", "..", "README.md")).read()
    section = readme[readme.index("### S3 for a PyTorch network") :]
    code = section[section.index("```python") + len("```python") :]
    code = code[: code.index("```")]
    assert len(code.strip().splitlines()) <= 22
    code = code.replace("steps = 1000", "steps = 3").replace('"synth/manifest.json"', repr(str(manifest)))
    code = code.replace("crop=(256, 512)", "crop=(32, 48)").replace("num_workers=2", "num_workers=0")
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "examples"))
    from s3_train import CostVolumeNet

    scope: dict[str, Any] = {"MyStereoNet": lambda: CostVolumeNet(max_disparity=16)}
    exec(compile(code + "\nlosses = out.total.item()\n", "README.md", "exec"), scope)
    assert np.isfinite(scope["losses"])
    assert scope["batch"]["step"] == 2
