"""The argument checks of ``mbs.torch``.

Each refusal is a ``ValueError`` (a ``TypeError`` for a value of the wrong
type) whose message begins with the argument's name, then what it got and
what it expects.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from numbers import Real
from typing import SupportsIndex, cast

import torch

RIGHT, LEFT = "right", "left"


def require(ok: bool, name: str, value: object, expected: str) -> None:
    """Refuse an argument unless a condition holds.

    Parameters
    ----------
    ok : bool
        Whether the argument is acceptable.
    name : str
        The argument's name, which begins the message.
    value : object
        What it got, as the message shows it.
    expected : str
        What it expects.

    Raises
    ------
    ValueError
        ``"NAME: got VALUE, expected EXPECTED"`` unless ``ok``.
    """
    if not ok:
        raise ValueError(f"{name}: got {value}, expected {expected}")


def integer(name: str, value: object, minimum: int | None = None, maximum: int | None = None) -> int:
    """Check an integer argument.

    Parameters
    ----------
    name : str
        The argument's name.
    value : object
        Any integer: Python's, NumPy's, a 0-d integer tensor (anything with
        ``__index__``); not a bool or a float.
    minimum, maximum : int, optional
        The inclusive range, open where ``None``.

    Returns
    -------
    int
        ``value`` as an ``int``.

    Raises
    ------
    TypeError
        ``value`` is not an integer, or is a bool.
    ValueError
        ``value`` is outside ``[minimum, maximum]``.
    """
    if isinstance(value, bool):
        raise TypeError(f"{name}: got a bool ({value}), expected an integer")
    try:
        # `operator.index` refuses what has no `__index__`, with a TypeError.
        number = operator.index(cast(SupportsIndex, value))
    except TypeError:
        raise TypeError(f"{name}: got {type(value).__name__} {value!r}, expected an integer") from None
    low = "" if minimum is None else f" >= {minimum}"
    high = "" if maximum is None else f" <= {maximum}"
    require(
        (minimum is None or number >= minimum) and (maximum is None or number <= maximum),
        name,
        number,
        f"an integer{low}{' and' if low and high else ''}{high}",
    )
    return number


def number(name: str, value: object, minimum: float | None = None, maximum: float | None = None) -> float:
    """Check a real-number argument.

    Parameters
    ----------
    name : str
        The argument's name.
    value : object
        A real number (``numbers.Real``, not a bool) or a one-element
        tensor.
    minimum, maximum : float, optional
        The inclusive range, open where ``None``.

    Returns
    -------
    float
        ``value`` as a finite ``float``.

    Raises
    ------
    TypeError
        ``value`` is not a number, or is a bool.
    ValueError
        ``value`` is a tensor of more than one element, not finite, or
        outside ``[minimum, maximum]``.
    """
    if isinstance(value, bool) or not isinstance(value, (Real, torch.Tensor)):
        raise TypeError(f"{name}: got {type(value).__name__} {value!r}, expected a number")
    if isinstance(value, torch.Tensor):
        require(value.numel() == 1, name, f"a tensor of shape {tuple(value.shape)}", "a number")
    result = float(value)
    if minimum is not None and maximum is not None:
        expected = f"a finite number in [{minimum}, {maximum}]"
    elif minimum is not None:
        expected = f"a finite number >= {minimum}"
    else:
        expected = "a finite number"
    require(
        math.isfinite(result) and (minimum is None or result >= minimum) and (maximum is None or result <= maximum),
        name,
        result,
        expected,
    )
    return result


def flag(name: str, value: object) -> bool:
    """Check a flag.

    Parameters
    ----------
    name : str
        The argument's name.
    value : object
        The argument.

    Returns
    -------
    bool
        ``value``.

    Raises
    ------
    TypeError
        ``value`` is not a ``bool``.
    """
    if not isinstance(value, bool):
        raise TypeError(f"{name}: got {type(value).__name__} {value!r}, expected True or False")
    return value


def tensor(name: str, value: object, dims: int | None = None, floating: bool = True) -> torch.Tensor:
    """Check a tensor argument.

    Parameters
    ----------
    name : str
        The argument's name.
    value : object
        The argument.
    dims : int, optional
        The number of dimensions it must have.
    floating : bool, default True
        Whether it must be floating-point.

    Returns
    -------
    torch.Tensor
        ``value``.

    Raises
    ------
    TypeError
        ``value`` is not a tensor.
    ValueError
        It is not floating-point (with ``floating``) or has another number
        of dimensions than ``dims``.
    """
    if not isinstance(value, torch.Tensor):
        raise TypeError(f"{name}: got {type(value).__name__}, expected a torch.Tensor")
    if floating:
        require(value.is_floating_point(), name, value.dtype, "a floating-point tensor")
    if dims is not None:
        require(value.dim() == dims, name, f"shape {list(value.shape)}", f"a tensor of {dims} dimensions")
    return value


def images(name: str, value: object, channels: int | None = None) -> torch.Tensor:
    """Check a batch of images.

    Parameters
    ----------
    name : str
        The argument's name.
    value : object
        The argument: a non-empty floating-point batch ``[B, C, H, W]`` of
        images of at least one pixel.
    channels : int, optional
        The number of channels ``C`` it must have.

    Returns
    -------
    torch.Tensor
        ``value``.

    Raises
    ------
    TypeError
        ``value`` is not a tensor.
    ValueError
        It is not such a batch.
    """
    checked = tensor(name, value, dims=4)
    batch, depth, height, width = checked.shape
    require(batch > 0, name, "an empty batch", "at least one item")
    require(height > 0 and width > 0, name, f"{height}x{width} pixels", "images of at least one pixel")
    if channels is not None:
        require(depth == channels, name, f"{depth} channels", f"{channels} ([B, {channels}, H, W])")
    return checked


def shaped(name: str, value: object, shape: Sequence[int]) -> torch.Tensor:
    """Check a floating-point tensor of a given shape.

    Parameters
    ----------
    name : str
        The argument's name.
    value : object
        The argument.
    shape : sequence of int
        The shape it must have, exactly.

    Returns
    -------
    torch.Tensor
        ``value``.

    Raises
    ------
    TypeError
        ``value`` is not a tensor.
    ValueError
        It is not floating-point or has another shape.
    """
    checked = tensor(name, value)
    require(tuple(checked.shape) == tuple(shape), name, f"shape {list(checked.shape)}", f"shape {list(shape)}")
    return checked


def on_device(name: str, value: torch.Tensor, like_name: str, like: torch.Tensor) -> None:
    """Check that a tensor is on another's device.

    Parameters
    ----------
    name : str
        The argument's name.
    value : torch.Tensor
        The argument.
    like_name : str
        The other argument's name.
    like : torch.Tensor
        The other argument.

    Raises
    ------
    ValueError
        ``value`` is on another device than ``like``.
    """
    require(value.device == like.device, name, f"a tensor on {value.device}", f"{like_name}'s device, {like.device}")


def sides(name: str, value: object, batch: int) -> list[str]:
    """Check the target sides of a batch.

    Parameters
    ----------
    name : str
        The argument's name.
    value : object
        The argument: a sequence (not a string) of ``"left"``/``"right"``.
    batch : int
        The number of items, one side each.

    Returns
    -------
    list of str
        ``value`` as a list.

    Raises
    ------
    TypeError
        ``value`` is a string or not a sequence.
    ValueError
        It has another length than ``batch`` or a side that is neither
        ``"left"`` nor ``"right"``.
    """
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise TypeError(f"{name}: got {value!r}, expected a list of 'left'/'right', one per batch item")
    listed = list(value)
    require(len(listed) == batch, name, f"{len(listed)} sides", f"one per batch item ({batch})")
    bad = [side for side in listed if side not in (RIGHT, LEFT)]
    require(not bad, name, repr(bad[0]) if bad else "", "'left' or 'right'")
    return listed
