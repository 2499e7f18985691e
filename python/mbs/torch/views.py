"""Target sides and the mirroring of left targets, as ``mbs-tool train``.

A stereo network expects its target on the right. An item whose target
lies left of its reference is mirrored along x on the way in and its
prediction mirrored back, so every network sees a right-hand pair and every
disparity is positive.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Callable, Union

import torch

from mbs.torch import _checks
from mbs.torch._checks import LEFT as LEFT  # re-exported: `mbs.torch` takes them from here
from mbs.torch._checks import RIGHT as RIGHT

#: A stereo network: ``network(left, right)`` returns the left view's
#: disparity, or a list or tuple of them (an iterative network).
Network = Callable[[torch.Tensor, torch.Tensor], Union[torch.Tensor, list[torch.Tensor], tuple[torch.Tensor, ...]]]


def side_signs(sides: Sequence[str], batch: int, name: str, like: torch.Tensor) -> torch.Tensor:
    """Give the warp's sign of each item from its target side.

    Parameters
    ----------
    sides : sequence of str
        ``"left"``/``"right"``, one per item.
    batch : int
        The number of items.
    name : str
        The argument's name, for errors.
    like : torch.Tensor
        A tensor whose dtype and device the signs take.

    Returns
    -------
    torch.Tensor
        ``[B, 1, 1, 1]``: +1 for a target on the right (a pixel samples its
        target at ``x - d``), -1 on the left (``x + d``).

    Raises
    ------
    TypeError
        ``sides`` is a string or not a sequence.
    ValueError
        It has another length than ``batch`` or an unknown side.
    """
    checked = _checks.sides(name, sides, batch)
    signs = [1.0 if side == RIGHT else -1.0 for side in checked]
    return torch.tensor(signs, dtype=like.dtype, device=like.device).view(batch, 1, 1, 1)


def mirror_left(tensor: torch.Tensor, sides: Sequence[str]) -> torch.Tensor:
    """Flip along x the items whose target is on the left.

    Parameters
    ----------
    tensor : torch.Tensor
        A batch ``[B, ..., W]`` of any dtype.
    sides : sequence of str
        ``"left"``/``"right"``, one per item.

    Returns
    -------
    torch.Tensor
        ``tensor`` with its left items flipped along the last axis
        (``tensor`` itself when every side is ``"right"``).

    Raises
    ------
    TypeError
        ``tensor`` is not a tensor, or ``sides`` not a sequence.
    ValueError
        ``tensor`` has fewer than 2 dimensions, or ``sides`` another length
        than the batch or an unknown side.
    """
    _checks.tensor("tensor", tensor, floating=False)
    _checks.require(tensor.dim() >= 2, "tensor", f"shape {list(tensor.shape)}", "a batch [B, ..., W]")
    checked = _checks.sides("sides", sides, tensor.shape[0])
    if all(side == RIGHT for side in checked):
        return tensor
    if all(side == LEFT for side in checked):
        return tensor.flip(-1)
    # Tensor.split has no annotations in torch (torch.split has, but would
    # hand tensor subclasses' __torch_function__ another function).
    parts = tensor.split(1, 0)  # type: ignore[no-untyped-call]
    items = [item.flip(-1) if side == LEFT else item for item, side in zip(parts, checked)]
    return torch.cat(items, 0)


def predict(
    network: Network, reference: torch.Tensor, target: torch.Tensor, sides: Sequence[str]
) -> list[torch.Tensor]:
    """Run a stereo network on pairs whose targets lie on either side.

    Runs ``network(left, right)`` on each pair, left targets mirrored, and
    mirrors its predictions back.

    Parameters
    ----------
    network : callable
        ``network(left, right)`` on ``[B, 3, H, W]`` images (target on the
        right) returns the left image's disparity ``[B, 1, H, W]`` or ``[B,
        H, W]``, or a list or tuple of them (an iterative network), such as
        an ``nn.Module``.
    reference : torch.Tensor
        Reference images ``[B, 3, H, W]``.
    target : torch.Tensor
        Target images, the same shape on the same device.
    sides : sequence of str
        Each item's target side, ``"left"`` or ``"right"``.

    Returns
    -------
    list of torch.Tensor
        The predictions, first to last (one for a network that returns one
        disparity), each ``[B, 1, H, W]`` on the reference grid: a channel
        axis is added to ``[B, H, W]``.

    Raises
    ------
    TypeError
        An image is not a tensor, or ``sides`` not a sequence.
    ValueError
        ``network`` is not callable or returns no prediction or one of
        another shape; an image has the wrong shape or device; or
        ``sides`` is wrong (the message begins with the argument's name).
    """
    _checks.require(callable(network), "network", type(network).__name__, "a callable network(left, right)")
    _checks.images("reference", reference)
    _checks.shaped("target", target, reference.shape)
    _checks.on_device("target", target, "reference", reference)
    batch, _, height, width = reference.shape
    checked = _checks.sides("sides", sides, batch)
    out = network(mirror_left(reference, checked), mirror_left(target, checked))
    predictions: list[torch.Tensor] | tuple[torch.Tensor, ...] = out if isinstance(out, (list, tuple)) else [out]
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
        result.append(mirror_left(prediction, checked))
    return result
