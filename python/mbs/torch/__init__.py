"""S3 for any PyTorch stereo network (torch is an optional dependency).

- :class:`MultiBaselineDataset`: the batches ``mbs-tool train`` draws
  (triplets, crops, ratios, augmentation draws), one item per step, and
  :func:`augment_batch`, the student's augmented input from its draws;
- :class:`S3Loss`: the paper's loss with every term, mask and switch of
  ``mbs-tool train``, on tensors and autograd;
- :func:`predict`: runs ``network(left, right)`` with left targets mirrored;
- :func:`sequence_weights`, :func:`cosine_momentum`, :func:`ema_update_`,
  :func:`geometry_weight`: the iterative student's weights, the EMA
  teacher and the geometry term's warm-up.

A whole training loop is ``python/examples/s3_train.py``.
"""

try:
    import torch as _torch  # noqa: F401
except ImportError as error:  # pragma: no cover - depends on the environment
    raise ImportError("mbs.torch needs PyTorch: pip install torch") from error

from mbs.torch.augment import augment_batch, augment_pair
from mbs.torch.data import MultiBaselineDataset
from mbs.torch.loss import S3Loss, S3LossOutput, photometric_map, ssim, warp_to_reference
from mbs.torch.schedules import cosine_momentum, ema_update_, geometry_weight, sequence_weights
from mbs.torch.views import LEFT, RIGHT, mirror_left, predict

__all__ = [
    "LEFT",
    "MultiBaselineDataset",
    "RIGHT",
    "S3Loss",
    "S3LossOutput",
    "augment_batch",
    "augment_pair",
    "cosine_momentum",
    "ema_update_",
    "geometry_weight",
    "mirror_left",
    "photometric_map",
    "predict",
    "sequence_weights",
    "ssim",
    "warp_to_reference",
]
