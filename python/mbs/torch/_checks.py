"""The argument checks of ``mbs.torch``: each refusal is a ``ValueError``
(a ``TypeError`` for a value of the wrong type) whose message begins with
the argument's name, then what it got and what it expects."""

import math
import operator
from numbers import Real
from typing import List, Optional, Sequence

import torch

RIGHT, LEFT = "right", "left"


def require(ok: bool, name: str, value, expected: str) -> None:
    """Raises ``ValueError("NAME: got VALUE, expected EXPECTED")`` unless ``ok``."""
    if not ok:
        raise ValueError(f"{name}: got {value}, expected {expected}")


def integer(name: str, value, minimum: Optional[int] = None, maximum: Optional[int] = None) -> int:
    """``value`` as an ``int`` (any integer: Python's, NumPy's, a 0-d
    integer tensor; not a bool or a float) within ``[minimum, maximum]``."""
    if isinstance(value, bool):
        raise TypeError(f"{name}: got a bool ({value}), expected an integer")
    try:
        number = operator.index(value)
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


def number(name: str, value, minimum: Optional[float] = None, maximum: Optional[float] = None) -> float:
    """``value`` as a finite ``float`` within ``[minimum, maximum]`` (not a bool)."""
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
        math.isfinite(result)
        and (minimum is None or result >= minimum)
        and (maximum is None or result <= maximum),
        name,
        result,
        expected,
    )
    return result


def flag(name: str, value) -> bool:
    """``value`` if it is a ``bool``."""
    if not isinstance(value, bool):
        raise TypeError(f"{name}: got {type(value).__name__} {value!r}, expected True or False")
    return value


def tensor(name: str, value, dims: Optional[int] = None, floating: bool = True) -> torch.Tensor:
    """``value`` if it is a tensor (of ``dims`` dimensions; floating-point
    unless ``floating`` is false)."""
    if not isinstance(value, torch.Tensor):
        raise TypeError(f"{name}: got {type(value).__name__}, expected a torch.Tensor")
    if floating:
        require(value.is_floating_point(), name, value.dtype, "a floating-point tensor")
    if dims is not None:
        require(value.dim() == dims, name, f"shape {list(value.shape)}", f"a tensor of {dims} dimensions")
    return value


def images(name: str, value, channels: Optional[int] = None) -> torch.Tensor:
    """``value`` if it is a non-empty floating-point batch ``[B, C, H, W]``
    (with ``channels`` channels when given)."""
    tensor(name, value, dims=4)
    batch, depth, height, width = value.shape
    require(batch > 0, name, "an empty batch", "at least one item")
    require(height > 0 and width > 0, name, f"{height}x{width} pixels", "images of at least one pixel")
    if channels is not None:
        require(depth == channels, name, f"{depth} channels", f"{channels} ([B, {channels}, H, W])")
    return value


def shaped(name: str, value, shape: Sequence[int]) -> torch.Tensor:
    """``value`` if it is a floating-point tensor of exactly ``shape``."""
    tensor(name, value)
    require(tuple(value.shape) == tuple(shape), name, f"shape {list(value.shape)}", f"shape {list(shape)}")
    return value


def on_device(name: str, value: torch.Tensor, like_name: str, like: torch.Tensor) -> None:
    """Refuses ``value`` unless it is on ``like``'s device."""
    require(value.device == like.device, name, f"a tensor on {value.device}", f"{like_name}'s device, {like.device}")


def sides(name: str, value, batch: int) -> List[str]:
    """``value`` as a list of ``"left"``/``"right"``, one per batch item."""
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise TypeError(f"{name}: got {value!r}, expected a list of 'left'/'right', one per batch item")
    value = list(value)
    require(len(value) == batch, name, f"{len(value)} sides", f"one per batch item ({batch})")
    bad = [side for side in value if side not in (RIGHT, LEFT)]
    require(not bad, name, repr(bad[0]) if bad else "", "'left' or 'right'")
    return value
