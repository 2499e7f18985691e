"""`mbs.torch` against the Rust trainer: on the fixed inputs of
`fixtures/torch_parity.safetensors` (written by the Rust example
`torch_parity_fixture`, see its doc for the command), every case of
`S3Loss` gives the Rust loss's total, terms, masks, weight map and
gradient in each student prediction: masks pixel for pixel, values within
2e-5 relative (f32, sums in another order), gradients within 1e-6 absolute
plus 1e-4 relative; `augment_pair` gives the trainer's augmented pair
within 1e-6 from the same draws. Then the loss's invariants on their own:
a prediction far outside the image is pulled back, and bad arguments are
`ValueError`s that name them.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from mbs.torch import (
    S3Loss,
    S3LossOutput,
    augment_pair,
    cosine_momentum,
    ema_update_,
    mirror_left,
    predict,
    sequence_weights,
)

FIXTURE = Path(__file__).parent / "fixtures" / "torch_parity.safetensors"


def read_safetensors(path: Path) -> tuple[dict[str, torch.Tensor], dict[str, str]]:
    """Tensors and metadata of a safetensors file (f32 only)."""
    raw = path.read_bytes()
    (length,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8 : 8 + length])
    metadata = header.pop("__metadata__", {})
    body = raw[8 + length :]
    tensors = {}
    for name, info in header.items():
        assert info["dtype"] == "F32", f"{name}: {info['dtype']}"
        start, end = info["data_offsets"]
        tensors[name] = torch.from_numpy(np.frombuffer(body[start:end], dtype="<f4").reshape(info["shape"]).copy())
    return tensors, metadata


TENSORS, METADATA = read_safetensors(FIXTURE)
CASES = json.loads(METADATA["cases"])


def sides_of(signs: torch.Tensor) -> list[str]:
    return ["right" if s > 0 else "left" for s in signs.tolist()]


def run_case(case: dict[str, Any]) -> tuple[S3LossOutput, list[torch.Tensor]]:
    inputs = {name.split("/", 1)[1]: t for name, t in TENSORS.items() if name.startswith("inputs/")}
    count = case["predictions"]
    predictions = [inputs[f"student_disparity_{i}"].clone().requires_grad_(True) for i in range(3 - count, 3)]
    loss = S3Loss(**case["config"], sequence_gamma=case["sequence_gamma"])
    sides = sides_of(inputs["signs"])
    out = loss(
        inputs["reference"],
        inputs["student_target"],
        inputs["teacher_target"],
        predictions if count > 1 else predictions[0],
        inputs["teacher_disparity"],
        sides,
        sides,
        inputs["ratios"].tolist(),
        geometry_weight=case["geometry_weight"],
    )
    out.total.backward()
    return out, predictions


@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_loss_matches_the_rust_trainer(case: dict[str, Any]) -> None:
    name = case["name"]
    out, predictions = run_case(case)
    for part in ["student_mask", "teacher_mask", "weight_map"]:
        expected = TENSORS.get(f"{name}/{part}")
        got = getattr(out, part)
        assert (got is None) == (expected is None), f"{name}/{part}: switched on in one loss only"
        if expected is not None:
            differ = (got != expected).sum().item()
            assert differ == 0, f"{name}/{part}: {differ} of {expected.numel()} pixels differ"
    for part in ["total", "geometry", "photometric", "smoothness", "range", "view"]:
        expected = TENSORS.get(f"{name}/{part}")
        got = getattr(out, part)
        assert (got is None) == (expected is None), f"{name}/{part}: switched on in one loss only"
        if expected is not None:
            assert got.item() == pytest.approx(expected.item(), rel=2e-5, abs=1e-7), f"{name}/{part}"
    for i, prediction in enumerate(predictions):
        expected = TENSORS[f"{name}/grad_{i}"]
        torch.testing.assert_close(prediction.grad, expected, rtol=1e-4, atol=1e-6, msg=f"{name}/grad_{i}")


def test_augmentation_matches_the_trainer() -> None:
    draws = {name: TENSORS[f"augment/{name}"] for name in ["brightness", "contrast", "saturation", "occlusion"]}
    reference, target = augment_pair(TENSORS["inputs/reference"], TENSORS["inputs/student_target"], **draws)
    torch.testing.assert_close(reference, TENSORS["augment/reference"], rtol=0, atol=1e-6)
    torch.testing.assert_close(target, TENSORS["augment/target"], rtol=0, atol=1e-6)
    # The draws did something: factors away from 1 and rectangles erased.
    assert (draws["brightness"] - 1).abs().max() > 0.05
    assert 0 < draws["occlusion"].mean() < 1


def test_the_fixture_exercises_every_part() -> None:
    """Masks are neither empty nor full, warps leave the image, and the
    range term has something to pull back: else parity would prove little."""
    for part in ["student_mask", "teacher_mask"]:
        share = TENSORS[f"default/{part}"].mean().item()
        assert 0.2 < share < 0.9, f"{part}: {share}"
    assert TENSORS["default/range"].item() > 0.5
    default = TENSORS["default/total"].item()
    for case in CASES[1:]:
        total = TENSORS[f"{case['name']}/total"].item()
        assert abs(total - default) > 1e-4, f"{case['name']} computes the default loss"
    assert TENSORS["paper/student_mask"].sum() > TENSORS["default/student_mask"].sum()


def test_a_prediction_outside_the_image_is_pulled_back() -> None:
    """Disparities past the image (warps that read only the border) have
    no photometric or geometry gradient; the range term still moves them
    toward the image, and the paper's loss (range_weight 0) does not."""
    torch.manual_seed(0)
    reference, target = torch.rand(1, 3, 8, 16), torch.rand(1, 3, 8, 16)
    for range_weight, pulls in [(1.0, True), (0.0, False)]:
        disparity = torch.full((1, 1, 8, 16), -200.0, requires_grad=True)
        loss = S3Loss(range_weight=range_weight, smoothness=False)
        out = loss(reference, target, target, disparity, disparity.detach(), ["right"], ["right"], [0.5])
        assert out.student_mask.sum() == 0
        if pulls:
            out.total.backward()
            # Gradient descent raises every disparity toward [0, W - 1].
            assert (disparity.grad < 0).all()  # type: ignore[operator, union-attr]  # backward() set it
        else:
            assert not out.total.requires_grad or torch.autograd.grad(out.total, disparity)[0].abs().max() == 0


def test_a_warp_past_the_targets_edge_is_pulled_back() -> None:
    """Disparities inside [0, W - 1] but too large for their column read
    the clamped border: no photometric gradient, and the range term does
    not see them. The view term lowers them toward the edge."""
    torch.manual_seed(0)
    reference, target = torch.rand(1, 3, 8, 16), torch.rand(1, 3, 8, 16)
    for view_weight, pulls in [(1.0, True), (0.0, False)]:
        # 12 px at every column: the warps of columns 0-11 land left of the target.
        disparity = torch.full((1, 1, 8, 16), 12.0, requires_grad=True)
        loss = S3Loss(view_weight=view_weight, geometry=False, smoothness=False)
        out = loss(reference, target, target, disparity, disparity.detach(), ["right"], ["right"], [0.5])
        assert out.range.item() == 0
        grad = torch.autograd.grad(out.total, disparity)[0]
        outside = grad[..., :11]
        if pulls:
            assert out.view.item() == pytest.approx(sum(12 - x for x in range(12)) / 16, rel=1e-6)
            # Gradient descent lowers every disparity whose warp leaves the target.
            assert (outside > 0).all()
        else:
            assert out.view is None
            assert (outside == 0).all()


def test_bad_arguments_name_themselves() -> None:
    image = torch.rand(2, 3, 8, 16)
    disparity = torch.rand(2, 1, 8, 16)
    loss = S3Loss()
    call: dict[str, Any] = dict(
        reference=image,
        student_target=image,
        teacher_target=image,
        student_disparity=disparity,
        teacher_disparity=disparity,
        student_sides=["right", "left"],
        teacher_sides=["right", "left"],
        ratios=[0.5, 0.5],
    )
    changes: list[tuple[dict[str, Any], str]] = [
        ({"student_disparity": torch.rand(2, 8, 16)}, "student_disparity"),
        ({"teacher_target": torch.rand(2, 3, 8, 15)}, "teacher_target"),
        ({"student_sides": ["right", "up"]}, "student_sides"),
        ({"teacher_sides": ["right"]}, "teacher_sides"),
        ({"ratios": [0.5]}, "ratios"),
        ({"reference": image.to(torch.int64)}, "reference"),
        ({"student_disparity": []}, "student_disparity"),
    ]
    for change, named in changes:
        with pytest.raises(ValueError, match=named):
            loss(**{**call, **change})
    with pytest.raises(ValueError, match="reference"):
        loss(
            **{
                **call,
                "reference": torch.rand(2, 3, 2, 16),
                "student_target": torch.rand(2, 3, 2, 16),
                "teacher_target": torch.rand(2, 3, 2, 16),
                "student_disparity": torch.rand(2, 1, 2, 16),
                "teacher_disparity": torch.rand(2, 1, 2, 16),
            }
        )
    settings: list[tuple[dict[str, Any], str]] = [
        ({"tau": 0}, "tau"),
        ({"ssim_window": 4}, "ssim_window"),
        ({"alpha": 2}, "alpha"),
        ({"geometry": False, "photometric": False, "smoothness": False}, "geometry"),
    ]
    for kwargs, named in settings:
        with pytest.raises(ValueError, match=named):
            S3Loss(**kwargs)


def test_sequence_weights_and_momentum_follow_the_trainer() -> None:
    # gamma' = 0.9^(15/2): the first of three weighs 0.9^15.
    assert sequence_weights(3, 0.9) == pytest.approx([0.9**15, 0.9**7.5, 1.0])
    assert sequence_weights(3, 0.9, final_only=True) == [0.0, 0.0, 1.0]
    assert sequence_weights(1) == [1.0]
    assert cosine_momentum(0, 100, 0.996) == pytest.approx(0.996)
    assert cosine_momentum(50, 100, 0.996) == pytest.approx(0.998)
    assert cosine_momentum(100, 100, 0.996) == 1.0
    assert cosine_momentum(500, 100, 0.996) == 1.0


def test_ema_update_blends_parameters_and_refuses_other_networks() -> None:
    student, teacher = torch.nn.Linear(3, 2), torch.nn.Linear(3, 2)
    before = teacher.weight.detach().clone()
    ema_update_(teacher, student, 0.75)
    torch.testing.assert_close(teacher.weight, 0.75 * before + 0.25 * student.weight.detach())
    with pytest.raises(ValueError, match="teacher"):
        ema_update_(torch.nn.Linear(3, 4), student, 0.5)
    with pytest.raises(ValueError, match="momentum"):
        ema_update_(teacher, student, 1.5)


def test_predict_mirrors_left_targets_in_and_out() -> None:
    """A network that returns its input's first channel: a left item's
    prediction is its reference (mirrored twice), and lists are kept."""
    reference = torch.arange(2 * 3 * 2 * 4, dtype=torch.float32).view(2, 3, 2, 4)
    network = lambda left, right: [left[:, :1] * 0.5, left[:, 0]]  # noqa: E731
    first, last = predict(network, reference, reference, ["right", "left"])
    torch.testing.assert_close(last, reference[:, :1])
    torch.testing.assert_close(first, reference[:, :1] * 0.5)
    torch.testing.assert_close(mirror_left(reference, ["left", "left"]), reference.flip(-1))
