"""The weights and schedules of an S3 run, as ``mbs-tool train``: the
sequence weights of an iterative student, the EMA teacher's momentum and
its update."""

import math
from typing import List

import torch
from torch import nn

from mbs.torch import _checks


def sequence_weights(n: int, gamma: float = 0.9, final_only: bool = False) -> List[float]:
    """The loss weight of each of ``n`` predictions, first to last:
    ``gamma'^(n - 1 - i)`` with ``gamma' = gamma^(15 / (n - 1))``, as the
    official RAFT-Stereo and IGEV-Stereo sequence losses; the final
    prediction weighs 1, and with ``final_only`` the others weigh 0.
    ``n`` is at least 1, ``gamma`` in ``[0, 1]``."""
    n = _checks.integer("n", n, minimum=1)
    gamma = _checks.number("gamma", gamma, 0.0, 1.0)
    _checks.flag("final_only", final_only)
    if n == 1 or final_only:
        return [0.0] * (n - 1) + [1.0]
    adjusted = gamma ** (15.0 / (n - 1))
    return [adjusted ** (n - 1 - i) for i in range(n)]


def cosine_momentum(step: int, total_steps: int, base: float = 0.996) -> float:
    """The EMA momentum at ``step``: ``base`` at step 0, rising to 1 at
    ``total_steps`` (at least 1) on a cosine (BYOL's schedule)."""
    step = _checks.integer("step", step, minimum=0)
    total_steps = _checks.integer("total_steps", total_steps, minimum=1)
    base = _checks.number("base", base, 0.0, 1.0)
    progress = min(step, total_steps) / total_steps
    return 1.0 - (1.0 - base) * (math.cos(math.pi * progress) + 1.0) / 2.0


@torch.no_grad()
def ema_update_(teacher: nn.Module, student: nn.Module, momentum: float) -> None:
    """Sets every parameter of ``teacher`` to
    ``momentum * teacher + (1 - momentum) * student``, in place (buffers
    such as batch-norm statistics are left alone, as in ``mbs-tool train``).
    The two networks must have the same parameters in the same order."""
    for name, network in [("teacher", teacher), ("student", student)]:
        _checks.require(isinstance(network, nn.Module), name, type(network).__name__, "a torch.nn.Module")
    momentum = _checks.number("momentum", momentum, 0.0, 1.0)
    teacher_params, student_params = list(teacher.parameters()), list(student.parameters())
    if len(teacher_params) != len(student_params):
        raise ValueError(
            f"teacher: {len(teacher_params)} parameters, the student has {len(student_params)}"
        )
    for index, (t, s) in enumerate(zip(teacher_params, student_params)):
        if t.shape != s.shape:
            raise ValueError(f"teacher: parameter {index} is {tuple(t.shape)}, the student's {tuple(s.shape)}")
        t.mul_(momentum).add_(s.detach().to(t.device), alpha=1.0 - momentum)


def geometry_weight(step: int, total_steps: int, start: float = 0.0, warmup: float = 0.0) -> float:
    """The geometry term's weight at ``step`` of a ``total_steps`` run, as
    ``trainer.geometry_start`` and ``trainer.geometry_warmup``: 0 for the
    first ``start`` share of the steps, then rising linearly to 1 over the
    next ``warmup`` share (both rounded to whole steps), then 1. The
    defaults weigh it fully from the first step (the paper); ``mbs-tool
    train`` uses 0.3 and 0.5 for RAFT-Stereo and IGEV-Stereo from random
    weights. ``total_steps`` is at least 1."""
    step = _checks.integer("step", step, minimum=0)
    total_steps = _checks.integer("total_steps", total_steps, minimum=1)
    start = _checks.number("start", start, 0.0, 1.0)
    warmup = _checks.number("warmup", warmup, 0.0, 1.0)
    _checks.require(start + warmup <= 1.0, "start + warmup", start + warmup, "at most 1")
    start_step = round(start * total_steps)
    warmup_steps = round((start + warmup) * total_steps) - start_step
    if step < start_step:
        return 0.0
    if warmup_steps == 0:
        return 1.0
    return min((step - start_step) / warmup_steps, 1.0)
