"""``MultiBaselineDataset``: the batches ``mbs-tool train`` draws, as a
PyTorch dataset."""

import json
from typing import Optional, Sequence, Tuple

import torch
from torch.utils.data import Dataset

from mbs import _native
from mbs.torch import _checks


class MultiBaselineDataset(Dataset):
    """The training batches of a manifest's ``train`` samples, one dataset
    item per training step: item ``k`` is the whole batch of step ``k``,
    drawn and decoded in Rust by the code ``mbs-tool train`` runs, so it
    has the same samples, triplets, crops, baseline ratios and augmentation
    draws as step ``k`` of ``mbs-tool train --seed SEED --batch-size B
    --crop HxW`` (with the same ``augment`` settings). Every choice of
    step ``k`` depends on the seed and ``k`` alone, so the batches do not
    depend on ``DataLoader`` workers or their order.

    Use it with automatic batching off::

        data = MultiBaselineDataset("synth/manifest.json", steps=1000, batch_size=4, crop=(256, 512))
        loader = DataLoader(data, batch_size=None, shuffle=False, num_workers=2)
        for batch in loader:
            ...

    Each batch is a dict: ``reference``, ``student_target`` and
    ``teacher_target`` (clean crops, ``float32 [B, 3, H, W]`` in ``[0, 1]``),
    ``ratios`` (``float32 [B]``, ``r = B_s / B_t``), ``student_sides`` and ``teacher_sides``
    (``"left"``/``"right"`` per item), ``triplets`` (``int64 [B, 3]``:
    reference, student and teacher view), ``windows`` (``int64 [B, 2]``:
    the crop's top and left), ``sample_ids``, ``step``, ``skipped``
    (unreadable images that were replaced), and the draws of the student's
    augmentation (``brightness``, ``contrast``, ``saturation``,
    ``occlusion``), which :func:`mbs.torch.augment_batch` applies where the
    network runs (the student's input; the loss and the teacher see the
    clean crops).

    ``augment`` takes ``mbs-tool train``'s ``augment.*`` keys
    (``brightness``, ``contrast``, ``saturation``, ``occlusion_probability``,
    ``occlusion_max_rects``, ``occlusion_min_side``, ``occlusion_max_side``);
    missing ones keep the paper's values, unknown ones are refused as
    ``mbs-tool train --set`` refuses them. A manifest that cannot be used
    is an ``OSError`` naming it; a bad setting a ``ValueError`` naming it
    (a ``TypeError`` for a value of the wrong type, such as a float
    ``batch_size``).
    """

    def __init__(
        self,
        manifest,
        steps: int,
        batch_size: int = 16,
        crop: Tuple[int, int] = (384, 512),
        seed: int = 0,
        augment: Optional[dict] = None,
    ):
        steps = _checks.integer("steps", steps, minimum=1)
        crop = _crop(crop)
        _checks.require(
            augment is None or isinstance(augment, dict), "augment", type(augment).__name__, "a dict of settings"
        )
        self._arguments = (str(manifest), batch_size, crop[0], crop[1], seed, json.dumps(augment or {}))
        self.steps = steps
        self._batches = _native.HostBatches(*self._arguments)

    def __len__(self) -> int:
        return self.steps

    def __getitem__(self, step: int) -> dict:
        step = _checks.integer("step", step)
        if not 0 <= step < self.steps:
            raise IndexError(f"step {step} of a {self.steps}-step dataset")
        raw = self._batches.batch(step)
        batch = {name: torch.from_numpy(raw[name]) for name in _TENSORS}
        batch["ratios"] = batch["ratios"].to(torch.float32)
        for name in ("student_sides", "teacher_sides", "sample_ids", "skipped"):
            batch[name] = raw[name]
        batch["step"] = step
        return batch

    def __getstate__(self):
        # The Rust side is rebuilt in each worker process from the arguments.
        return {"arguments": self._arguments, "steps": self.steps}

    def __setstate__(self, state):
        self._arguments, self.steps = state["arguments"], state["steps"]
        self._batches = _native.HostBatches(*self._arguments)


_TENSORS = (
    "reference",
    "student_target",
    "teacher_target",
    "ratios",
    "triplets",
    "windows",
    "brightness",
    "contrast",
    "saturation",
    "occlusion",
)


def _crop(crop: Sequence[int]) -> Tuple[int, int]:
    """``(height, width)``, integers; their range is checked in Rust."""
    _checks.require(
        isinstance(crop, Sequence) and not isinstance(crop, str) and len(crop) == 2,
        "crop",
        repr(crop),
        "(height, width)",
    )
    return _checks.integer("crop height", crop[0]), _checks.integer("crop width", crop[1])
