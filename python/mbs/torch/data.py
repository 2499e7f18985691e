"""``MultiBaselineDataset``: the batches ``mbs-tool train`` draws, as a PyTorch dataset."""

from __future__ import annotations

import json
from collections.abc import Sequence
from os import PathLike
from typing import Any, Literal, SupportsIndex, get_args

import torch
from torch.utils.data import Dataset

from mbs import _native
from mbs.torch import _checks


class MultiBaselineDataset(Dataset[dict[str, Any]]):
    """The training batches of a manifest's ``train`` samples, one item per step.

    Item ``k`` is the whole batch of step ``k``, drawn and decoded in Rust by
    the code ``mbs-tool train`` runs, so it has the same samples, triplets,
    crops, baseline ratios and augmentation draws as step ``k`` of ``mbs-tool
    train --seed SEED --batch-size B --crop HxW`` (with the same ``augment``
    settings). Every choice of step ``k`` depends on the seed and ``k``
    alone, so the batches do not depend on ``DataLoader`` workers or their
    order.

    Parameters
    ----------
    manifest : str or os.PathLike
        The dataset's manifest; its ``train`` samples are drawn, each at
        least the crop's size.
    steps : int
        The number of steps, the dataset's length: at least 1.
    batch_size : int, default 16
        Items per batch, 1 to 1024.
    crop : sequence of two int, default (384, 512)
        ``(height, width)`` of the crops, each side 16 to 32768.
    seed : int, default 0
        The run's seed, 0 to ``2**64 - 1``.
    augment : dict, optional
        ``mbs-tool train``'s ``augment.*`` keys (``brightness``,
        ``contrast``, ``saturation``, ``occlusion_probability``,
        ``occlusion_max_rects``, ``occlusion_min_side``,
        ``occlusion_max_side``); missing ones keep the paper's values,
        unknown ones are refused as ``mbs-tool train --set`` refuses them.

    Raises
    ------
    OSError
        The manifest cannot be used (it is named), or a sample is smaller
        than the crop.
    ValueError
        A setting is out of range or unknown (the message begins with its
        name).
    TypeError
        A setting has the wrong type, such as a float ``batch_size``.

    See Also
    --------
    mbs.torch.augment_batch : The student's input from a batch's draws.

    Notes
    -----
    Use it with automatic batching off::

        data = MultiBaselineDataset("synth/manifest.json", steps=1000, batch_size=4, crop=(256, 512))
        loader = DataLoader(data, batch_size=None, shuffle=False, num_workers=2)
        for batch in loader:
            ...

    Each batch is a dict: ``reference``, ``student_target`` and
    ``teacher_target`` (clean crops, ``float32 [B, 3, H, W]`` in ``[0, 1]``),
    ``ratios`` (``float32 [B]``, ``r = B_s / B_t``), ``student_sides`` and
    ``teacher_sides`` (``"left"``/``"right"`` per item), ``triplets``
    (``int64 [B, 3]``: reference, student and teacher view), ``windows``
    (``int64 [B, 2]``: the crop's top and left), ``sample_ids``, ``step``,
    ``skipped`` (unreadable images that were replaced, each ``(path,
    error)``), and the draws of the student's augmentation
    (``brightness``, ``contrast``, ``saturation``, ``occlusion``), which
    :func:`mbs.torch.augment_batch` applies where the network runs (the
    student's input; the loss and the teacher see the clean crops).
    """

    def __init__(
        self,
        manifest: str | PathLike[str],
        steps: SupportsIndex,
        batch_size: SupportsIndex = 16,
        crop: Sequence[SupportsIndex] = (384, 512),
        seed: SupportsIndex = 0,
        augment: dict[str, Any] | None = None,
    ) -> None:
        checked_steps = _checks.integer("steps", steps, minimum=1)
        height, width = _crop(crop)
        _checks.require(
            augment is None or isinstance(augment, dict), "augment", type(augment).__name__, "a dict of settings"
        )
        self._arguments = (str(manifest), batch_size, height, width, seed, json.dumps(augment or {}))
        self.steps = checked_steps
        self._batches = _native.HostBatches(*self._arguments)

    def __len__(self) -> int:
        """Return the number of steps.

        Returns
        -------
        int
            ``steps``.
        """
        return self.steps

    def __getitem__(self, step: SupportsIndex) -> dict[str, Any]:
        """Return the batch of a step.

        Parameters
        ----------
        step : int
            The step, ``0`` to ``steps - 1``.

        Returns
        -------
        dict
            The batch (see the class's notes for its keys), on the CPU.

        Raises
        ------
        TypeError
            ``step`` is not an integer.
        IndexError
            ``step`` is outside the dataset.
        OSError
            The batch cannot be read.
        """
        index = _checks.integer("step", step)
        if not 0 <= index < self.steps:
            raise IndexError(f"step {index} of a {self.steps}-step dataset")
        raw = self._batches.batch(index)
        batch: dict[str, Any] = {name: torch.from_numpy(raw[name]) for name in _TENSORS}
        batch["ratios"] = batch["ratios"].to(torch.float32)
        for name in _LISTS:
            batch[name] = raw[name]
        batch["step"] = index
        return batch

    def __getstate__(self) -> dict[str, Any]:
        """Return the dataset's arguments, for pickling.

        Returns
        -------
        dict
            What :meth:`__setstate__` rebuilds the dataset from.
        """
        # The Rust side is rebuilt in each worker process from the arguments.
        return {"arguments": self._arguments, "steps": self.steps}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Rebuild the dataset from its arguments.

        Parameters
        ----------
        state : dict
            What :meth:`__getstate__` returned.

        Raises
        ------
        OSError
            The manifest can no longer be used.
        """
        self._arguments, self.steps = state["arguments"], state["steps"]
        self._batches = _native.HostBatches(*self._arguments)


#: The arrays of a batch, as tensors: names of keys of the native batch's
#: typed dict (``mbs/_native.pyi``), so that they index it.
_TensorName = Literal[
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
]
_TENSORS: tuple[_TensorName, ...] = get_args(_TensorName)

#: The lists of a batch, as they are.
_ListName = Literal["student_sides", "teacher_sides", "sample_ids", "skipped"]
_LISTS: tuple[_ListName, ...] = get_args(_ListName)


def _crop(crop: Sequence[SupportsIndex]) -> tuple[int, int]:
    """Check a crop size; its range is checked in Rust.

    Parameters
    ----------
    crop : sequence of two int
        ``(height, width)``, as the caller gave it.

    Returns
    -------
    tuple of int
        ``(height, width)``.

    Raises
    ------
    ValueError
        ``crop`` is not a sequence of two.
    TypeError
        A side is not an integer.
    """
    _checks.require(
        isinstance(crop, Sequence) and not isinstance(crop, str) and len(crop) == 2,
        "crop",
        repr(crop),
        "(height, width)",
    )
    return _checks.integer("crop height", crop[0]), _checks.integer("crop width", crop[1])
