"""The S3 loss on PyTorch tensors (paper eq. 7), term for term ``mbs-tool train``'s.

The loss of crates/mbs-train/src/losses:

``L = g mean(A |d_s - r d_t|) + lambda_p mean(M_s P_s) + lambda_s L_s + lambda_r R + lambda_v V``

- ``P`` is the photometric error ``alpha (1 - SSIM) / 2 + (1 - alpha) L1``
  (box SSIM of side ``ssim_window``, reflection padding), averaged over
  channels; the target is warped to the reference with linear
  interpolation along x, clamped at the border;
- ``M_s`` and ``M_t`` are the validity masks ``P < tau`` (threshold
  filtering) and ``P < P_identity`` (auto-masking), without the pixels
  whose warp leaves the target when ``out_of_view_invalid``;
- ``A = M_t (M_s + omega (1 - M_s))`` (occlusion-aware enhancement);
- ``L_s`` is the edge-aware smoothness of the student's disparity;
- ``R`` is the mean distance (px) of the student's disparities outside
  ``[0, W - 1]``: 0 for any plausible prediction, a way back for one that
  left the image;
- ``V`` is the mean distance (px) by which the student's warps land
  outside the target image: a way back for disparities too large for
  their pixel's column, where the clamped warp has no gradient;
- ``g`` is the geometry weight of the step (the trainer's warm-up);
- with ``outside_mask_weight`` ``beta``, ``M_s`` in the photometric term
  becomes ``M_s + beta (1 - M_s)``: pixels outside the student's mask keep
  a photometric gradient;
- with ``photometric_mask_mean``, ``mean(M_s P_s)`` becomes
  ``sum(M_s P_s) / sum(M_s)``, the mean over the student's mask (those
  weights).

Disparities that are not finite (NaN, ``inf``) are invalid pixels, as
everywhere in mbs, where ``inf`` marks a pixel with no value: a teacher's
carry no target (they leave ``M_t``), a student's take no part in any term
and get no gradient, so one overflowed pixel (an f16 network, say) does not
turn the whole step into NaN; ``S3LossOutput.student_non_finite`` counts
them, without a device sync, for a loop that stops a diverged run. They
never reach the warp's index.

``range_weight=0`` and ``out_of_view_invalid=False`` are the paper's loss
exactly; the defaults are ``mbs-tool train``'s for its compact network,
and for RAFT-Stereo and IGEV-Stereo it adds ``geometry_scale_match=True``
and ``outside_mask_weight=0.1`` (with warm-ups of the geometry term and
the learning rate), for IGEV-Stereo also ``view_weight=0.1`` (README, "S3
from random weights").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import SupportsIndex, Union

import torch
from torch import nn

from mbs.torch import _checks
from mbs.torch.schedules import sequence_weights
from mbs.torch.views import side_signs

#: SSIM stabilisers for images in ``[0, 1]``.
_C1 = 0.01**2
_C2 = 0.03**2


@dataclass
class S3LossOutput:
    """The loss and its parts; a part whose term is switched off is ``None``.

    The terms are the final prediction's, before their weights; the masks
    are 0/1 maps ``[B, 1, H, W]`` without gradient.

    Parameters
    ----------
    total : torch.Tensor
        The loss, a 0-d tensor differentiable in the student's disparities.
    geometry : torch.Tensor, optional
        ``mean(A |d_s - r d_t|)``.
    photometric : torch.Tensor, optional
        ``mean(M_s P_s)`` (or its mask-mean form).
    smoothness : torch.Tensor, optional
        ``L_s``, the edge-aware smoothness.
    range : torch.Tensor, optional
        ``R``, the mean distance of disparities outside ``[0, W - 1]``.
    view : torch.Tensor, optional
        ``V``, the mean distance of warps outside the target.
    student_mask : torch.Tensor, optional
        ``M_s``.
    teacher_mask : torch.Tensor, optional
        ``M_t``.
    weight_map : torch.Tensor, optional
        ``A``.
    student_non_finite : torch.Tensor, optional
        The number of the final prediction's pixels that were not finite (a
        0-d tensor on its device), left out of every term.
    """

    total: torch.Tensor
    geometry: torch.Tensor | None = None
    photometric: torch.Tensor | None = None
    smoothness: torch.Tensor | None = None
    range: torch.Tensor | None = None
    view: torch.Tensor | None = None
    student_mask: torch.Tensor | None = None
    teacher_mask: torch.Tensor | None = None
    weight_map: torch.Tensor | None = None
    student_non_finite: torch.Tensor | None = None


def _window_sums(tensor: torch.Tensor, dim: int, window: int) -> torch.Tensor:
    """Sum ``tensor`` over windows of ``window`` along ``dim`` (valid windows only)."""
    outputs = tensor.shape[dim] + 1 - window
    zero_shape = list(tensor.shape)
    zero_shape[dim] = 1
    prefix = torch.cat([tensor.new_zeros(zero_shape), tensor.cumsum(dim)], dim)
    return prefix.narrow(dim, window, outputs) - prefix.narrow(dim, 0, outputs)


def _window_means(tensor: torch.Tensor, window: int) -> torch.Tensor:
    """Mean of ``tensor`` ``[B, C, H, W]`` over ``window x window`` boxes (valid boxes only)."""
    return _window_sums(_window_sums(tensor, 2, window), 3, window) / float(window * window)


def ssim(x: torch.Tensor, y: torch.Tensor, window: SupportsIndex) -> torch.Tensor:
    """Compute the per-pixel, per-channel SSIM of two images.

    On a box window with reflection padding.

    Parameters
    ----------
    x : torch.Tensor
        Images ``[B, C, H, W]`` in ``[0, 1]``.
    y : torch.Tensor
        Images of the same shape on the same device.
    window : int
        The box's side: odd, and half of it less than each side of the
        images.

    Returns
    -------
    torch.Tensor
        ``[B, C, H, W]``.

    Raises
    ------
    TypeError
        An image is not a tensor or ``window`` not an integer.
    ValueError
        The images differ in shape or device, or ``window`` does not fit
        (the message begins with the argument's name).
    """
    _checks.images("x", x)
    _checks.shaped("y", y, x.shape)
    _checks.on_device("y", y, "x", x)
    window = _checks.integer("window", window, minimum=1)
    _checks.require(window % 2 == 1, "window", window, "an odd window side such as 3 or 7")
    height, width = x.shape[2:]
    _checks.require(window // 2 < min(height, width), "window", window, f"a window that fits {height}x{width} images")
    pad = window // 2
    x = torch.nn.functional.pad(x - 0.5, (pad, pad, pad, pad), mode="reflect")
    y = torch.nn.functional.pad(y - 0.5, (pad, pad, pad, pad), mode="reflect")
    mean_x, mean_y = _window_means(x, window), _window_means(y, window)
    sigma_x = _window_means(x * x, window) - mean_x * mean_x
    sigma_y = _window_means(y * y, window) - mean_y * mean_y
    sigma_xy = _window_means(x * y, window) - mean_x * mean_y
    mu_x, mu_y = mean_x + 0.5, mean_y + 0.5
    numerator = (mu_x * mu_y * 2.0 + _C1) * (sigma_xy * 2.0 + _C2)
    denominator = (mu_x * mu_x + mu_y * mu_y + _C1) * (sigma_x + sigma_y + _C2)
    return numerator / denominator


def photometric_map(
    reference: torch.Tensor, reconstructed: torch.Tensor, alpha: float, window: SupportsIndex
) -> torch.Tensor:
    """Compute the photometric error of a reconstruction, per pixel.

    ``alpha clamp((1 - SSIM) / 2, 0, 1) + (1 - alpha) |I_r - I|``, averaged
    over channels.

    Parameters
    ----------
    reference : torch.Tensor
        Images ``[B, C, H, W]`` in ``[0, 1]``.
    reconstructed : torch.Tensor
        Images of the same shape on the same device (a warped target).
    alpha : float
        The SSIM share, in ``[0, 1]``.
    window : int
        The SSIM window's side, as :func:`ssim`.

    Returns
    -------
    torch.Tensor
        ``[B, 1, H, W]``.

    Raises
    ------
    TypeError
        As :func:`ssim`, or ``alpha`` is not a number.
    ValueError
        As :func:`ssim`, or ``alpha`` is outside ``[0, 1]``.
    """
    alpha = _checks.number("alpha", alpha, 0.0, 1.0)
    dissimilarity = ((1.0 - ssim(reference, reconstructed, window)) / 2.0).clamp(0.0, 1.0)
    l1 = (reference - reconstructed).abs()
    return (dissimilarity * alpha + l1 * (1.0 - alpha)).mean(dim=1, keepdim=True)


def sample_columns(disparity: torch.Tensor, signs: torch.Tensor) -> torch.Tensor:
    """Give the column each reference pixel samples in its target.

    ``x - d`` for a target on the right (sign +1), ``x + d`` on the left
    (sign -1).

    Parameters
    ----------
    disparity : torch.Tensor
        ``[B, 1, H, W]``.
    signs : torch.Tensor
        ``[B, 1, 1, 1]``, +1 or -1 per item.

    Returns
    -------
    torch.Tensor
        ``[B, 1, H, W]``: the columns, not clamped.
    """
    width = disparity.shape[3]
    columns = torch.arange(width, dtype=disparity.dtype, device=disparity.device).view(1, 1, 1, width)
    return columns - disparity * signs


def warp_to_reference(target: torch.Tensor, disparity: torch.Tensor, signs: torch.Tensor) -> torch.Tensor:
    """Warp target images to the reference grid by disparity.

    The target is sampled at ``x - sign d`` with linear interpolation along
    x, clamped to the border. A disparity that is not finite samples column
    0 (NaN) or the border (``inf``), without gradient: it never reaches the
    index.

    Parameters
    ----------
    target : torch.Tensor
        Images ``[B, C, H, W]``, at least 2 pixels wide.
    disparity : torch.Tensor
        ``[B, 1, H, W]`` on the target's device.
    signs : torch.Tensor
        ``[B, 1, 1, 1]``: +1 for a target on the right, -1 on the left.

    Returns
    -------
    torch.Tensor
        ``[B, C, H, W]``, differentiable in ``disparity`` and ``target``.

    Raises
    ------
    TypeError
        An argument is not a tensor.
    ValueError
        An argument has the wrong shape, dtype or device (the message
        begins with its name).
    """
    _checks.images("target", target)
    batch, channels, height, width = target.shape
    _checks.require(width >= 2, "target", f"{height}x{width} pixels", "images at least 2 pixels wide")
    _checks.shaped("disparity", disparity, (batch, 1, height, width))
    _checks.shaped("signs", signs, (batch, 1, 1, 1))
    for name, tensor in [("disparity", disparity), ("signs", signs)]:
        _checks.on_device(name, tensor, "target", target)
    x = torch.nan_to_num(sample_columns(disparity, signs), nan=0.0).clamp(0.0, width - 1)
    left = x.detach().floor().clamp(max=width - 2)
    weight = x - left
    left = left.long().expand(batch, channels, height, width)
    return target.gather(3, left) * (1.0 - weight) + target.gather(3, left + 1) * weight


def lands_inside(disparity: torch.Tensor, signs: torch.Tensor) -> torch.Tensor:
    """Mark the pixels whose warp lands inside the target.

    Parameters
    ----------
    disparity : torch.Tensor
        ``[B, 1, H, W]``.
    signs : torch.Tensor
        ``[B, 1, 1, 1]``, as :func:`sample_columns`.

    Returns
    -------
    torch.Tensor
        ``[B, 1, H, W]`` in ``disparity``'s dtype: 1 where a pixel's warp
        lands inside the target, 0 where it leaves it; no gradient.
    """
    columns = sample_columns(disparity.detach(), signs)
    return ((columns >= 0.0) & (columns <= disparity.shape[3] - 1)).to(disparity.dtype)


def validity_mask(
    photometric: torch.Tensor, identity: torch.Tensor, tau: float | None, auto_mask: bool
) -> torch.Tensor:
    """Mask the pixels whose warp explains the target (threshold filtering and auto-masking).

    Parameters
    ----------
    photometric : torch.Tensor
        The warped target's photometric error ``[B, 1, H, W]``.
    identity : torch.Tensor
        The unwarped target's, the same shape.
    tau : float or None
        The threshold; ``None`` switches threshold filtering off.
    auto_mask : bool
        Whether the warped error must beat the identity error.

    Returns
    -------
    torch.Tensor
        ``[B, 1, H, W]``: 1 where the warped error is below ``tau`` and the
        identity error, for the parts switched on (strict inequalities),
        else 0; no gradient.
    """
    photometric = photometric.detach()
    mask = torch.ones_like(photometric)
    if tau is not None:
        mask = mask * (photometric < tau).to(mask.dtype)
    if auto_mask:
        mask = mask * (photometric < identity.detach()).to(mask.dtype)
    return mask


def weight_map(teacher_mask: torch.Tensor, student_mask: torch.Tensor, omega: float) -> torch.Tensor:
    """Compute the geometry term's weights ``A = M_t (M_s + omega (1 - M_s))``.

    Parameters
    ----------
    teacher_mask : torch.Tensor
        ``M_t``, 0/1 ``[B, 1, H, W]``.
    student_mask : torch.Tensor
        ``M_s``, the same shape.
    omega : float
        The weight of pixels outside the student's mask (occlusion-aware
        enhancement).

    Returns
    -------
    torch.Tensor
        ``A``, ``[B, 1, H, W]``.
    """
    return teacher_mask * (student_mask * (1.0 - omega) + omega)


def match_scale(target: torch.Tensor, student: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """Rescale the geometry target per item to the student's weighted mean.

    Parameters
    ----------
    target : torch.Tensor
        The teacher's scaled disparity ``[B, 1, H, W]``.
    student : torch.Tensor
        The student's disparity, the same shape (not differentiated).
    weights : torch.Tensor
        The pixels' weights, the same shape.

    Returns
    -------
    torch.Tensor
        ``target`` times a per-item factor that makes its weighted mean the
        student's; an item with no weight keeps its target.
    """
    student_sum = (weights * student.detach()).sum(dim=(1, 2, 3), keepdim=True)
    target_sum = (weights * target).sum(dim=(1, 2, 3), keepdim=True)
    has_weight = (target_sum.abs() > 1e-6).to(target.dtype)
    scale = student_sum / target_sum.abs().clamp(min=1e-6) * has_weight + (1.0 - has_weight)
    return target * scale


def geometry_consistency(
    student: torch.Tensor,
    teacher: torch.Tensor,
    ratios: torch.Tensor,
    weights: torch.Tensor,
    cap: float | None,
    scale_match: bool,
) -> torch.Tensor:
    """Compute the geometry term ``mean(weights |d_s - r d_t|)``.

    Parameters
    ----------
    student : torch.Tensor
        The student's disparity ``d_s``, ``[B, 1, H, W]``.
    teacher : torch.Tensor
        The teacher's ``d_t``, the same shape (detached).
    ratios : torch.Tensor
        The baseline ratios ``r``, ``[B]``.
    weights : torch.Tensor
        ``[B, 1, H, W]``, such as :func:`weight_map`'s.
    cap : float or None
        Pixels whose target ``r d_t`` exceeds it weigh 0.
    scale_match : bool
        Whether the target is rescaled first (:func:`match_scale`).

    Returns
    -------
    torch.Tensor
        A 0-d tensor, differentiable in ``student``.
    """
    target = teacher.detach() * ratios.view(-1, 1, 1, 1)
    if cap is not None:
        weights = weights * (target <= cap).to(weights.dtype)
    if scale_match:
        target = match_scale(target, student, weights)
    return (weights * (student - target).abs()).mean()


def out_of_range(disparity: torch.Tensor) -> torch.Tensor:
    """Compute the range term ``mean(max(0, -d) + max(0, d - (W - 1)))``.

    Parameters
    ----------
    disparity : torch.Tensor
        ``[B, 1, H, W]``.

    Returns
    -------
    torch.Tensor
        A 0-d tensor: the mean distance (px) of the disparities outside
        ``[0, W - 1]``.
    """
    width = disparity.shape[3]
    return ((-disparity).clamp(min=0.0) + (disparity - (width - 1)).clamp(min=0.0)).mean()


def out_of_view(disparity: torch.Tensor, signs: torch.Tensor) -> torch.Tensor:
    """Compute the view term ``mean(max(0, -c) + max(0, c - (W - 1)))``.

    Parameters
    ----------
    disparity : torch.Tensor
        ``[B, 1, H, W]``.
    signs : torch.Tensor
        ``[B, 1, 1, 1]``, as :func:`sample_columns`.

    Returns
    -------
    torch.Tensor
        A 0-d tensor: the mean distance (px) by which the columns ``c``
        that the pixels sample in their target land outside it.
    """
    return out_of_range(sample_columns(disparity, signs))


def edge_aware_smoothness(
    disparity: torch.Tensor, image: torch.Tensor, normalise: bool, valid: torch.Tensor | None = None
) -> torch.Tensor:
    """Compute the edge-aware smoothness of a disparity.

    The mean of ``|d(x+1) - d(x)| exp(-|I(x+1) - I(x)|)`` over horizontal
    pairs plus the same over vertical pairs.

    Parameters
    ----------
    disparity : torch.Tensor
        ``[B, 1, H, W]``.
    image : torch.Tensor
        Its reference images ``[B, C, H, W]``.
    normalise : bool
        Whether each map is divided by its mean first.
    valid : torch.Tensor, optional
        0/1 ``[B, 1, H, W]``: a pair with an invalid pixel weighs 0.

    Returns
    -------
    torch.Tensor
        A 0-d tensor.
    """
    if normalise:
        disparity = disparity / (disparity.mean(dim=(2, 3), keepdim=True) + 1e-7)

    def term(dim: int) -> torch.Tensor:
        disparity_step = disparity.diff(dim=dim).abs()
        if valid is not None:
            length = valid.shape[dim] - 1
            disparity_step = disparity_step * valid.narrow(dim, 0, length) * valid.narrow(dim, 1, length)
        image_step = image.diff(dim=dim).abs().mean(dim=1, keepdim=True)
        return (disparity_step * torch.exp(-image_step)).mean()

    return term(3) + term(2)


#: What the terms of every prediction share (:meth:`S3Loss._shared`): the
#: student's identity error, and the teacher's mask and detached disparity.
_Shared = tuple[Union[torch.Tensor, None], Union[tuple[torch.Tensor, torch.Tensor], None]]


class S3Loss(nn.Module):
    """The S3 loss of ``mbs-tool train`` as an ``nn.Module``.

    With every switch of its ``trainer.loss`` settings (paper Tables 3 and
    4), keyword-only. Call it as :meth:`forward` says; it returns an
    :class:`S3LossOutput`.

    Parameters
    ----------
    tau : float, default 0.1
        The photometric threshold of the validity masks, positive.
    omega : float, default 2.0
        The weight of pixels the teacher sees and the student does not, at
        least 0.
    lambda_p : float, default 10.0
        The weight of the photometric term, at least 0.
    lambda_s_ratio : float, default 0.001
        ``lambda_s / lambda_p``, the smoothness term's weight over the
        photometric term's, at least 0.
    alpha : float, default 0.85
        The SSIM share of the photometric error, in ``[0, 1]``.
    ssim_window : int, default 7
        The SSIM box window's side, odd.
    geometry, photometric, smoothness : bool, default True
        Whether each term is on (Table 3); at least one is.
    threshold_filter : bool, default True
        Photometric threshold filtering ``P < tau`` in the masks (Table 4).
    auto_mask : bool, default True
        Auto-masking ``P < P_identity`` in the masks (Table 4).
    occlusion_enhancement : bool, default True
        Weight ``omega`` instead of 1 where only the teacher sees (Table 4).
    normalise_smoothness : bool, default False
        Divide each disparity map by its mean in the smoothness term, as
        monodepth2; off as the paper's eq. 3.
    max_target_disparity : float, default 0.0
        The largest target ``r d_t`` (px) the geometry term supervises; 0
        supervises every pixel.
    range_weight : float, default 1.0
        The weight of the range term ``R``; 0 is the paper's loss.
    view_weight : float, default 0.0
        The weight of the view term ``V``; 0 is the paper's loss.
    geometry_scale_match : bool, default False
        Rescale each item's geometry target to the student's weighted mean
        (:func:`match_scale`); off is the paper's term.
    out_of_view_invalid : bool, default True
        Count pixels whose warp leaves the target as invalid in both masks;
        off is the paper's loss.
    photometric_mask_mean : bool, default False
        Average the photometric term over the student's mask instead of
        over every pixel.
    outside_mask_weight : float, default 0.0
        The photometric weight ``beta`` of pixels outside the student's
        mask, in ``[0, 1]``; 0 is the paper's ``M_s P_s``.
    sequence_gamma : float, default 0.9
        The decay of an iterative student's sequence weights, in ``[0, 1]``
        (:func:`mbs.torch.sequence_weights`).
    final_prediction_only : bool, default False
        Whether only an iterative student's final prediction counts.

    Raises
    ------
    TypeError
        A setting has the wrong type (a float ``ssim_window``, a string
        flag).
    ValueError
        A setting is out of range, or every term is off (the message begins
        with the setting's name).

    Examples
    --------
    >>> loss_fn = S3Loss()
    >>> out = loss_fn(reference, student_target, teacher_target,
    ...               student_disparity, teacher_disparity,
    ...               ["right", "left"], ["right", "left"], [0.5, 0.25])  # doctest: +SKIP
    >>> out.total.backward()  # doctest: +SKIP
    """

    def __init__(
        self,
        *,
        tau: float = 0.1,
        omega: float = 2.0,
        lambda_p: float = 10.0,
        lambda_s_ratio: float = 0.001,
        alpha: float = 0.85,
        ssim_window: SupportsIndex = 7,
        geometry: bool = True,
        photometric: bool = True,
        smoothness: bool = True,
        threshold_filter: bool = True,
        auto_mask: bool = True,
        occlusion_enhancement: bool = True,
        normalise_smoothness: bool = False,
        max_target_disparity: float = 0.0,
        range_weight: float = 1.0,
        view_weight: float = 0.0,
        geometry_scale_match: bool = False,
        out_of_view_invalid: bool = True,
        photometric_mask_mean: bool = False,
        outside_mask_weight: float = 0.0,
        sequence_gamma: float = 0.9,
        final_prediction_only: bool = False,
    ) -> None:
        super().__init__()
        tau = _checks.number("tau", tau, minimum=0.0)
        _checks.require(tau > 0, "tau", tau, "a positive number")
        omega, lambda_p, lambda_s_ratio, max_target_disparity, range_weight, view_weight = (
            _checks.number(name, value, minimum=0.0)
            for name, value in [
                ("omega", omega),
                ("lambda_p", lambda_p),
                ("lambda_s_ratio", lambda_s_ratio),
                ("max_target_disparity", max_target_disparity),
                ("range_weight", range_weight),
                ("view_weight", view_weight),
            ]
        )
        alpha, outside_mask_weight, sequence_gamma = (
            _checks.number(name, value, 0.0, 1.0)
            for name, value in [
                ("alpha", alpha),
                ("outside_mask_weight", outside_mask_weight),
                ("sequence_gamma", sequence_gamma),
            ]
        )
        window = _checks.integer("ssim_window", ssim_window, minimum=1)
        _checks.require(window % 2 == 1, "ssim_window", window, "an odd window side such as 3 or 7")
        for name, value in [
            ("geometry", geometry),
            ("photometric", photometric),
            ("smoothness", smoothness),
            ("threshold_filter", threshold_filter),
            ("auto_mask", auto_mask),
            ("occlusion_enhancement", occlusion_enhancement),
            ("normalise_smoothness", normalise_smoothness),
            ("geometry_scale_match", geometry_scale_match),
            ("out_of_view_invalid", out_of_view_invalid),
            ("photometric_mask_mean", photometric_mask_mean),
            ("final_prediction_only", final_prediction_only),
        ]:
            _checks.flag(name, value)
        _checks.require(
            geometry or photometric or smoothness,
            "geometry/photometric/smoothness",
            "all False",
            "at least one loss term on",
        )
        self.tau, self.omega, self.alpha, self.ssim_window = tau, omega, alpha, window
        self.lambda_p, self.lambda_s = lambda_p, lambda_s_ratio * lambda_p
        self.geometry, self.photometric, self.smoothness = geometry, photometric, smoothness
        self.threshold = tau if threshold_filter else None
        self.auto_mask = auto_mask
        self.effective_omega = omega if occlusion_enhancement else 1.0
        self.normalise_smoothness = normalise_smoothness
        self.cap = max_target_disparity if max_target_disparity > 0 else None
        self.range_weight = range_weight
        self.view_weight = view_weight
        self.geometry_scale_match = geometry_scale_match
        self.out_of_view_invalid = out_of_view_invalid
        self.photometric_mask_mean = photometric_mask_mean
        self.outside_mask_weight = outside_mask_weight
        self.sequence_gamma = sequence_gamma
        self.final_prediction_only = final_prediction_only

    def forward(
        self,
        reference: torch.Tensor,
        student_target: torch.Tensor,
        teacher_target: torch.Tensor,
        student_disparity: torch.Tensor | list[torch.Tensor] | tuple[torch.Tensor, ...],
        teacher_disparity: torch.Tensor,
        student_sides: Sequence[str],
        teacher_sides: Sequence[str],
        ratios: Sequence[float] | torch.Tensor,
        geometry_weight: float = 1.0,
    ) -> S3LossOutput:
        """Compute the loss of a batch.

        Parameters
        ----------
        reference : torch.Tensor
            The clean reference images ``[B, 3, H, W]`` in ``[0, 1]``.
        student_target, teacher_target : torch.Tensor
            The clean target images of student and teacher, the same shape.
        student_disparity : torch.Tensor or list of torch.Tensor
            The student's disparity ``[B, 1, H, W]`` on the reference grid,
            with the gradient; or a list (or tuple) of an iterative
            student's predictions, first to last, weighted by
            :func:`mbs.torch.sequence_weights`.
        teacher_disparity : torch.Tensor
            The teacher's disparity ``[B, 1, H, W]``; pixels that are not
            finite carry no target.
        student_sides, teacher_sides : sequence of str
            Each item's target side, ``"left"`` or ``"right"``.
        ratios : sequence of float or torch.Tensor
            The baseline ratios ``r = B_s / B_t``, one finite positive
            number per item.
        geometry_weight : float, default 1.0
            The geometry term's weight ``g`` at this step
            (:func:`mbs.torch.geometry_weight`), at least 0.

        Returns
        -------
        S3LossOutput
            The loss and its parts.

        Raises
        ------
        TypeError
            A tensor argument is not a tensor, or sides not a sequence.
        ValueError
            An argument has the wrong shape, dtype, device or value (the
            message begins with its name).
        """
        predictions = list(student_disparity) if isinstance(student_disparity, (list, tuple)) else [student_disparity]
        _checks.require(len(predictions) > 0, "student_disparity", "an empty list", "a tensor or a non-empty list")
        batch = _check_shapes(
            reference, student_target, teacher_target, predictions, teacher_disparity, self.ssim_window
        )
        student_signs = side_signs(student_sides, batch, "student_sides", reference)
        teacher_signs = side_signs(teacher_sides, batch, "teacher_sides", reference)
        ratios = _baseline_ratios(ratios, batch, reference)
        geometry_weight = _checks.number("geometry_weight", geometry_weight, minimum=0.0)
        teacher_valid = torch.isfinite(teacher_disparity)
        teacher_disparity = torch.where(teacher_valid, teacher_disparity, teacher_disparity.new_zeros(()))
        shared = self._shared(
            reference, student_target, teacher_target, teacher_disparity, teacher_valid, teacher_signs
        )
        weights = sequence_weights(len(predictions), self.sequence_gamma, self.final_prediction_only)
        out = self._terms(reference, student_target, predictions[-1], student_signs, ratios, geometry_weight, shared)
        for prediction, weight in zip(predictions[:-1], weights[:-1]):
            if weight <= 0:
                continue
            earlier = self._terms(reference, student_target, prediction, student_signs, ratios, geometry_weight, shared)
            out.total = out.total + earlier.total * weight
        return out

    def _photometric(
        self, reference: torch.Tensor, target: torch.Tensor, warp: tuple[torch.Tensor, torch.Tensor] | None = None
    ) -> torch.Tensor:
        """Photometric error of ``target``, warped by ``(disparity, signs)`` if given."""
        if warp is not None:
            target = warp_to_reference(target, *warp)
        return photometric_map(reference, target, self.alpha, self.ssim_window)

    def _in_view(self, mask: torch.Tensor, disparity: torch.Tensor, signs: torch.Tensor) -> torch.Tensor:
        """``mask`` without the pixels whose warp leaves the target, when ``out_of_view_invalid``."""
        return mask * lands_inside(disparity, signs) if self.out_of_view_invalid else mask

    def _shared(
        self,
        reference: torch.Tensor,
        student_target: torch.Tensor,
        teacher_target: torch.Tensor,
        teacher_disparity: torch.Tensor,
        teacher_valid: torch.Tensor,
        teacher_signs: torch.Tensor,
    ) -> _Shared:
        """What every prediction's terms share: the student's identity error and the teacher's mask."""
        student_identity = None
        if self.photometric or self.geometry:
            student_identity = self._photometric(reference, student_target)
        teacher = None
        if self.geometry:
            disparity = teacher_disparity.detach()
            warped = self._photometric(reference, teacher_target, (disparity, teacher_signs))
            identity = self._photometric(reference, teacher_target)
            mask = validity_mask(warped, identity, self.threshold, self.auto_mask) * teacher_valid.to(warped.dtype)
            teacher = (self._in_view(mask, disparity, teacher_signs), disparity)
        return student_identity, teacher

    def _terms(
        self,
        reference: torch.Tensor,
        student_target: torch.Tensor,
        student: torch.Tensor,
        signs: torch.Tensor,
        ratios: torch.Tensor,
        geometry_weight: float,
        shared: _Shared,
    ) -> S3LossOutput:
        """The loss and its parts for one prediction of the student."""
        student_identity, teacher = shared
        finite = torch.isfinite(student)
        student = torch.where(finite, student, student.new_zeros(()))
        valid = finite.to(student.dtype)
        out = S3LossOutput(total=student.new_zeros(()), student_non_finite=(~finite).sum())
        total = student.new_zeros(())
        if student_identity is not None:
            p_s = self._photometric(reference, student_target, (student, signs))
            m_s = validity_mask(p_s, student_identity, self.threshold, self.auto_mask) * valid
            m_s = self._in_view(m_s, student, signs)
            if self.photometric:
                weights = (m_s * (1.0 - self.outside_mask_weight) + self.outside_mask_weight) * valid
                masked = weights * p_s
                if self.photometric_mask_mean:
                    out.photometric = masked.sum() / weights.sum().clamp_min(1.0)
                else:
                    out.photometric = masked.mean()
                total = total + out.photometric * self.lambda_p
            if teacher is not None:
                m_t, teacher_disparity = teacher
                a = weight_map(m_t, m_s, self.effective_omega) * valid
                out.geometry = geometry_consistency(
                    student, teacher_disparity, ratios, a, self.cap, self.geometry_scale_match
                )
                total = total + out.geometry * geometry_weight
                out.teacher_mask, out.weight_map = m_t, a
            out.student_mask = m_s
        if self.range_weight > 0:
            out.range = out_of_range(student)
            total = total + out.range * self.range_weight
        if self.view_weight > 0:
            out.view = out_of_view(student, signs)
            total = total + out.view * self.view_weight
        if self.smoothness:
            out.smoothness = edge_aware_smoothness(student, reference, self.normalise_smoothness, valid)
            total = total + out.smoothness * self.lambda_s
        out.total = total
        return out


def _check_shapes(
    reference: torch.Tensor,
    student_target: torch.Tensor,
    teacher_target: torch.Tensor,
    predictions: Sequence[torch.Tensor],
    teacher_disparity: torch.Tensor,
    window: int,
) -> int:
    """Check every tensor of a call and return the batch size.

    Types, shapes (a non-empty batch) and one device.
    """
    for name, tensor in [
        ("student_target", student_target),
        ("teacher_target", teacher_target),
        ("teacher_disparity", teacher_disparity),
    ] + [("student_disparity", p) for p in predictions]:
        _checks.tensor(name, tensor)
    _checks.images("reference", reference)
    batch, channels, height, width = reference.shape
    image, disparity = (batch, channels, height, width), (batch, 1, height, width)
    for name, tensor, want in [
        ("student_target", student_target, image),
        ("teacher_target", teacher_target, image),
        ("teacher_disparity", teacher_disparity, disparity),
    ] + [("student_disparity", p, disparity) for p in predictions]:
        _checks.require(tuple(tensor.shape) == want, name, tuple(tensor.shape), f"{list(want)}")
        _checks.on_device(name, tensor, "reference", reference)
    _checks.require(
        width >= 2 and window // 2 < min(height, width),
        "reference",
        f"{height}x{width}",
        f"images large enough for a {window}x{window} SSIM window",
    )
    return batch


def _baseline_ratios(ratios: Sequence[float] | torch.Tensor, batch: int, like: torch.Tensor) -> torch.Tensor:
    """Check the baseline ratios and return them as a ``[B]`` tensor on ``like``'s device.

    One finite positive number per item (a device sync when they are on a
    GPU already).
    """
    try:
        values = torch.as_tensor(ratios, dtype=like.dtype)
    except (TypeError, ValueError, RuntimeError):
        raise ValueError(f"ratios: got {ratios!r}, expected {batch} baseline ratios") from None
    _checks.require(values.shape == (batch,), "ratios", tuple(values.shape), f"{batch} baseline ratios")
    _checks.require(
        bool((torch.isfinite(values) & (values > 0)).all()), "ratios", values.tolist(), "finite positive ratios"
    )
    return values.to(device=like.device)


__all__: list[str] = ["S3Loss", "S3LossOutput", "photometric_map", "ssim", "warp_to_reference"]
