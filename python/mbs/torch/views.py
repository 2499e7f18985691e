"""Target sides and the mirroring of left targets, as ``mbs-tool train``.

A stereo network expects its target on the right. An item whose target
lies left of its reference is mirrored along x on the way in and its
prediction mirrored back, so every network sees a right-hand pair and every
disparity is positive.
"""

from typing import List, Sequence, Union

import torch

from mbs.torch import _checks
from mbs.torch._checks import LEFT, RIGHT


def side_signs(sides: Sequence[str], batch: int, name: str, like: torch.Tensor) -> torch.Tensor:
    """``[B, 1, 1, 1]`` signs: +1 for a target on the right (a pixel
    samples its target at ``x - d``), -1 on the left (``x + d``)."""
    sides = _checks.sides(name, sides, batch)
    signs = [1.0 if side == RIGHT else -1.0 for side in sides]
    return torch.tensor(signs, dtype=like.dtype, device=like.device).view(batch, 1, 1, 1)


def mirror_left(tensor: torch.Tensor, sides: Sequence[str]) -> torch.Tensor:
    """Flips along x the items of ``[B, ...]`` whose target is on the left
    (``sides``: ``"left"``/``"right"``, one per item)."""
    _checks.tensor("tensor", tensor, floating=False)
    _checks.require(tensor.dim() >= 2, "tensor", f"shape {list(tensor.shape)}", "a batch [B, ..., W]")
    sides = _checks.sides("sides", sides, tensor.shape[0])
    if all(side == RIGHT for side in sides):
        return tensor
    if all(side == LEFT for side in sides):
        return tensor.flip(-1)
    items = [item.flip(-1) if side == LEFT else item for item, side in zip(tensor.split(1, 0), sides)]
    return torch.cat(items, 0)


def predict(network, reference: torch.Tensor, target: torch.Tensor, sides: Sequence[str]) -> List[torch.Tensor]:
    """Runs ``network(left, right)`` on each pair, left targets mirrored,
    and returns its predictions mirrored back, first to last: one for a
    network that returns a disparity, all of them for one that returns a
    list (an iterative network). Each is ``[B, 1, H, W]``; a network that
    returns ``[B, H, W]`` gets its channel axis added. ``reference`` and
    ``target`` are ``[B, 3, H, W]`` on one device; ``sides`` has one
    ``"left"``/``"right"`` per item."""
    _checks.require(callable(network), "network", type(network).__name__, "a callable network(left, right)")
    _checks.images("reference", reference)
    _checks.shaped("target", target, reference.shape)
    _checks.on_device("target", target, "reference", reference)
    batch, _, height, width = reference.shape
    sides = _checks.sides("sides", sides, batch)
    out = network(mirror_left(reference, sides), mirror_left(target, sides))
    predictions: Union[list, tuple] = out if isinstance(out, (list, tuple)) else [out]
    _checks.require(len(predictions) > 0, "network", "an empty list of predictions", "at least one")
    result = []
    for prediction in predictions:
        _checks.require(
            isinstance(prediction, torch.Tensor)
            and tuple(prediction.shape) in ((batch, 1, height, width), (batch, height, width)),
            "network",
            f"a prediction of shape {list(getattr(prediction, 'shape', []))}"
            if isinstance(prediction, torch.Tensor)
            else type(prediction).__name__,
            f"disparities [B, 1, H, W] or [B, H, W] of the input's size, {[batch, 1, height, width]}",
        )
        if prediction.dim() == 3:
            prediction = prediction.unsqueeze(1)
        result.append(mirror_left(prediction, sides))
    return result
