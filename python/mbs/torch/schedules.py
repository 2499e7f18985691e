"""The weights and schedules of an S3 run, as ``mbs-tool train``.

The sequence weights of an iterative student, the EMA teacher's momentum and
its update, and the geometry term's warm-up.
"""

from __future__ import annotations

import math
from typing import SupportsIndex

import torch
from torch import nn

from mbs.torch import _checks


def sequence_weights(n: SupportsIndex, gamma: float = 0.9, final_only: bool = False) -> list[float]:
    """Weigh each of an iterative student's predictions.

    ``gamma'^(n - 1 - i)`` for prediction ``i`` with ``gamma' = gamma^(15 /
    (n - 1))``, as the official RAFT-Stereo and IGEV-Stereo sequence losses;
    the final prediction weighs 1.

    Parameters
    ----------
    n : int
        The number of predictions, at least 1.
    gamma : float, default 0.9
        The decay, in ``[0, 1]``.
    final_only : bool, default False
        Whether the predictions before the final one weigh 0.

    Returns
    -------
    list of float
        The loss weight of each prediction, first to last.

    Raises
    ------
    TypeError
        ``n`` is not an integer or ``final_only`` not a bool.
    ValueError
        ``n`` or ``gamma`` is out of range.
    """
    count = _checks.integer("n", n, minimum=1)
    gamma = _checks.number("gamma", gamma, 0.0, 1.0)
    _checks.flag("final_only", final_only)
    if count == 1 or final_only:
        return [0.0] * (count - 1) + [1.0]
    adjusted = gamma ** (15.0 / (count - 1))
    return [adjusted ** (count - 1 - i) for i in range(count)]


def cosine_momentum(step: SupportsIndex, total_steps: SupportsIndex, base: float = 0.996) -> float:
    """Give the EMA teacher's momentum at a step (BYOL's schedule).

    ``base`` at step 0, rising on a cosine to 1 at ``total_steps`` (and 1
    after it).

    Parameters
    ----------
    step : int
        The step, at least 0.
    total_steps : int
        The run's steps, at least 1.
    base : float, default 0.996
        The momentum at step 0, in ``[0, 1]``.

    Returns
    -------
    float
        The momentum.

    Raises
    ------
    TypeError
        ``step`` or ``total_steps`` is not an integer.
    ValueError
        An argument is out of range.
    """
    index = _checks.integer("step", step, minimum=0)
    total = _checks.integer("total_steps", total_steps, minimum=1)
    base = _checks.number("base", base, 0.0, 1.0)
    progress = min(index, total) / total
    return 1.0 - (1.0 - base) * (math.cos(math.pi * progress) + 1.0) / 2.0


@torch.no_grad()
def ema_update_(teacher: nn.Module, student: nn.Module, momentum: float) -> None:
    """Move the teacher's parameters toward the student's, in place.

    Every parameter of ``teacher`` becomes ``momentum * teacher + (1 -
    momentum) * student``; buffers such as batch-norm statistics are left
    alone, as in ``mbs-tool train``.

    Parameters
    ----------
    teacher : torch.nn.Module
        The EMA teacher, updated in place.
    student : torch.nn.Module
        The student, with the same parameters in the same order (on any
        device).
    momentum : float
        In ``[0, 1]``.

    Raises
    ------
    ValueError
        A network is not an ``nn.Module``, the two have different
        parameters, or ``momentum`` is out of range.
    """
    for name, network in [("teacher", teacher), ("student", student)]:
        _checks.require(isinstance(network, nn.Module), name, type(network).__name__, "a torch.nn.Module")
    momentum = _checks.number("momentum", momentum, 0.0, 1.0)
    teacher_params, student_params = list(teacher.parameters()), list(student.parameters())
    if len(teacher_params) != len(student_params):
        raise ValueError(f"teacher: {len(teacher_params)} parameters, the student has {len(student_params)}")
    for index, (t, s) in enumerate(zip(teacher_params, student_params)):
        if t.shape != s.shape:
            raise ValueError(f"teacher: parameter {index} is {tuple(t.shape)}, the student's {tuple(s.shape)}")
        t.mul_(momentum).add_(s.detach().to(t.device), alpha=1.0 - momentum)


def geometry_weight(step: SupportsIndex, total_steps: SupportsIndex, start: float = 0.0, warmup: float = 0.0) -> float:
    """Give the geometry term's weight at a step of a run.

    As ``trainer.geometry_start`` and ``trainer.geometry_warmup``: 0 for the
    first ``start`` share of the steps, then rising linearly to 1 over the
    next ``warmup`` share (both rounded to whole steps), then 1. The
    defaults weigh it fully from the first step (the paper); ``mbs-tool
    train`` uses 0.3 and 0.5 for RAFT-Stereo and IGEV-Stereo from random
    weights.

    Parameters
    ----------
    step : int
        The step, at least 0.
    total_steps : int
        The run's steps, at least 1.
    start : float, default 0.0
        The share of the run before the term, in ``[0, 1]``.
    warmup : float, default 0.0
        The share over which it then rises, in ``[0, 1]``; ``start +
        warmup`` is at most 1.

    Returns
    -------
    float
        The weight, in ``[0, 1]``.

    Raises
    ------
    TypeError
        ``step`` or ``total_steps`` is not an integer.
    ValueError
        An argument is out of range.
    """
    index = _checks.integer("step", step, minimum=0)
    total = _checks.integer("total_steps", total_steps, minimum=1)
    start = _checks.number("start", start, 0.0, 1.0)
    warmup = _checks.number("warmup", warmup, 0.0, 1.0)
    _checks.require(start + warmup <= 1.0, "start + warmup", start + warmup, "at most 1")
    start_step = round(start * total)
    warmup_steps = round((start + warmup) * total) - start_step
    if index < start_step:
        return 0.0
    if warmup_steps == 0:
        return 1.0
    return min((index - start_step) / warmup_steps, 1.0)
