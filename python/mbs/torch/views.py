"""Target sides and the mirroring of left targets, as ``mbs-tool train``.

A stereo network expects its target on the right. An item whose target
lies left of its reference is mirrored along x on the way in and its
prediction mirrored back, so every network sees a right-hand pair and every
disparity is positive.
"""

from typing import List, Sequence, Union

import torch

RIGHT, LEFT = "right", "left"


def side_signs(sides: Sequence[str], batch: int, name: str, like: torch.Tensor) -> torch.Tensor:
    """``[B, 1, 1, 1]`` signs: +1 for a target on the right (a pixel
    samples its target at ``x - d``), -1 on the left (``x + d``)."""
    sides = list(sides)
    if len(sides) != batch:
        raise ValueError(f"{name}: got {len(sides)} sides, expected one per batch item ({batch})")
    bad = [side for side in sides if side not in (RIGHT, LEFT)]
    if bad:
        raise ValueError(f"{name}: got {bad[0]!r}, expected 'left' or 'right'")
    signs = [1.0 if side == RIGHT else -1.0 for side in sides]
    return torch.tensor(signs, dtype=like.dtype, device=like.device).view(batch, 1, 1, 1)


def mirror_left(tensor: torch.Tensor, sides: Sequence[str]) -> torch.Tensor:
    """Flips along x the items of ``[B, ...]`` whose target is on the left."""
    sides = list(sides)
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
    returns ``[B, H, W]`` gets its channel axis added."""
    out = network(mirror_left(reference, sides), mirror_left(target, sides))
    predictions: Union[list, tuple] = out if isinstance(out, (list, tuple)) else [out]
    result = []
    for prediction in predictions:
        if prediction.dim() == 3:
            prediction = prediction.unsqueeze(1)
        result.append(mirror_left(prediction, sides))
    return result
