"""Seeded weights that mbs can reproduce bit for bit.

Every tensor of a state dict is filled from its own key: a SplitMix64 stream
seeded with the FNV-1a hash of the key gives 24-bit uniforms u in [0, 1).
`crates/mbs-train/src/backbone/seeded.rs` implements the same rule, so the
parity fixtures carry only inputs and outputs, not megabytes of weights.

Rule (by the last part of the key):
  weight of a convolution (2-D or more): (2u - 1) * sqrt(6 / fan_in)  (He uniform,
                           fan_in the product of every dimension but the first)
  bias:                    (2u - 1) * 0.1
  norm weight:             1 + (2u - 1) * 0.2
  running_mean:            (2u - 1) * 0.1
  running_var:             1 + u * 0.5
  num_batches_tracked:     left as it is (an integer counter)
"""

import math

import numpy as np

MASK = (1 << 64) - 1


def fnv1a(key: str) -> int:
    h = 0xCBF29CE484222325
    for byte in key.encode():
        h ^= byte
        h = (h * 0x100000001B3) & MASK
    return h


def uniforms(key: str, count: int) -> np.ndarray:
    """`count` uniforms in [0, 1) as float32, from the SplitMix64 stream of `key`."""
    state = np.uint64(fnv1a(key))
    steps = (np.arange(1, count + 1, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15))
    with np.errstate(over="ignore"):
        z = state + steps
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return ((z >> np.uint64(40)).astype(np.float32) / np.float32(1 << 24)).astype(np.float32)


def seeded_tensor(key: str, shape) -> np.ndarray:
    count = int(np.prod(shape)) if len(shape) else 1
    u = uniforms(key, count)
    two, one = np.float32(2.0), np.float32(1.0)
    name = key.rsplit(".", 1)[-1]
    if name == "weight" and len(shape) >= 2:
        fan_in = int(np.prod(shape[1:]))
        values = (two * u - one) * np.float32(math.sqrt(6.0 / fan_in))
    elif name == "weight":
        values = one + (two * u - one) * np.float32(0.2)
    elif name in ("bias", "running_mean"):
        values = (two * u - one) * np.float32(0.1)
    elif name == "running_var":
        values = one + u * np.float32(0.5)
    else:
        raise ValueError(f"no seeded rule for {key}")
    return values.astype(np.float32).reshape(shape)


def seed_module(module) -> None:
    """Overwrites every float tensor of `module.state_dict()` with its seeded values."""
    import torch

    state = module.state_dict()
    for key, tensor in state.items():
        if key.endswith("num_batches_tracked"):
            continue
        tensor.copy_(torch.from_numpy(seeded_tensor(key, tuple(tensor.shape))))
