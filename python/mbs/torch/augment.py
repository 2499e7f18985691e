"""The student's input augmentation of ``mbs-tool train`` on PyTorch tensors.

From the draws of a batch (``MultiBaselineDataset`` returns them): the same
colour jitter for both images of an item, then the target's occluding
rectangles filled with its mean colour. Apply it where the network runs, as
the trainer does: on a GPU it costs next to nothing, in a ``DataLoader``
worker it would cost more CPU time than decoding.
"""

from __future__ import annotations

from typing import Any

import torch

from mbs.torch import _checks

#: The draws of a batch that :func:`augment_batch` applies.
_DRAWS = ("brightness", "contrast", "saturation", "occlusion")


def _grey(images: torch.Tensor) -> torch.Tensor:
    """Luma ``0.299 R + 0.587 G + 0.114 B``, ``[B, 1, H, W]``."""
    return images[:, 0:1] * 0.299 + images[:, 1:2] * 0.587 + images[:, 2:3] * 0.114


def augment_pair(
    reference: torch.Tensor,
    target: torch.Tensor,
    brightness: torch.Tensor,
    contrast: torch.Tensor,
    saturation: torch.Tensor,
    occlusion: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Augment pairs of images with one batch's draws.

    Per item: brightness, then contrast around the image's mean grey, then
    saturation around each pixel's grey (clamped to ``[0, 1]``), both images
    alike; then the target is set to its mean colour where ``occlusion`` is
    1. The draws may be on another device than the images.

    Parameters
    ----------
    reference : torch.Tensor
        Reference images ``[B, 3, H, W]`` in ``[0, 1]``.
    target : torch.Tensor
        Target images, the same shape on the same device.
    brightness, contrast, saturation : torch.Tensor
        Factors ``[B]``, finite numbers.
    occlusion : torch.Tensor
        ``[B, 1, H, W]``: 1 where the target is erased, else 0.

    Returns
    -------
    tuple of torch.Tensor
        The augmented ``(reference, target)``, each ``[B, 3, H, W]``.

    Raises
    ------
    TypeError
        An argument is not a tensor.
    ValueError
        An argument has another shape, is not floating-point, ``target`` is
        on another device than ``reference``, or a factor is not finite
        (the message begins with the argument's name).
    """
    _checks.images("reference", reference, channels=3)
    _checks.shaped("target", target, reference.shape)
    _checks.on_device("target", target, "reference", reference)
    batch, _, height, width = reference.shape
    factors = []
    for name, factor in [("brightness", brightness), ("contrast", contrast), ("saturation", saturation)]:
        _checks.shaped(name, factor, (batch,))
        _checks.require(bool(torch.isfinite(factor).all()), name, factor.tolist(), "finite factors")
        factors.append(factor.to(reference).view(-1, 1, 1, 1))
    _checks.shaped("occlusion", occlusion, (batch, 1, height, width))

    def jitter(images: torch.Tensor) -> torch.Tensor:
        brightness, contrast, saturation = factors
        images = images * brightness
        mean_grey = _grey(images).mean(dim=(2, 3), keepdim=True)
        images = (images - mean_grey) * contrast + mean_grey
        pixel_grey = _grey(images)
        return ((images - pixel_grey) * saturation + pixel_grey).clamp(0.0, 1.0)

    reference, target = jitter(reference), jitter(target)
    mask = occlusion.to(target)
    mean_colour = target.mean(dim=(2, 3), keepdim=True)
    return reference, target * (1.0 - mask) + mean_colour * mask


def augment_batch(batch: dict[str, Any]) -> tuple[torch.Tensor, torch.Tensor]:
    """Augment a ``MultiBaselineDataset`` batch: the student's input.

    Parameters
    ----------
    batch : dict
        A batch of :class:`mbs.torch.MultiBaselineDataset` (at least its
        ``reference`` and ``student_target`` images and its draws
        ``brightness``, ``contrast``, ``saturation`` and ``occlusion``), on
        any device.

    Returns
    -------
    tuple of torch.Tensor
        ``(augmented reference, augmented target)`` on the device of its
        images, as :func:`augment_pair` makes them.

    Raises
    ------
    ValueError
        ``batch`` is not a dict or lacks a key; or as :func:`augment_pair`.
    TypeError
        As :func:`augment_pair`.
    """
    _checks.require(isinstance(batch, dict), "batch", type(batch).__name__, "a MultiBaselineDataset batch (a dict)")
    missing = [key for key in ("reference", "student_target") + _DRAWS if key not in batch]
    _checks.require(not missing, "batch", f"no {missing[0]!r}" if missing else "", "a MultiBaselineDataset batch")
    return augment_pair(batch["reference"], batch["student_target"], *(batch[name] for name in _DRAWS))
