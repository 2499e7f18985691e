"""S3 for any PyTorch stereo network (torch is an optional dependency).

- :class:`S3Loss`: the paper's loss with every term, mask and switch of
  ``mbs-tool train``, on tensors and autograd;
- :func:`predict`: runs ``network(left, right)`` with left targets mirrored;
- :func:`sequence_weights`, :func:`cosine_momentum`, :func:`ema_update_`:
  the iterative student's weights and the EMA teacher.

Example::

    from mbs.torch import S3Loss, predict, cosine_momentum, ema_update_
    loss_fn = S3Loss()
    with torch.no_grad():
        teacher_d = predict(teacher, ref, teacher_tgt, teacher_sides)[-1]
    student_d = predict(student, ref, student_tgt, student_sides)
    out = loss_fn(ref, student_tgt, teacher_tgt, student_d, teacher_d,
                  student_sides, teacher_sides, ratios)
    out.total.backward(); optimiser.step(); optimiser.zero_grad()
    ema_update_(teacher, student, cosine_momentum(step, total_steps))
"""

try:
    import torch as _torch  # noqa: F401
except ImportError as error:  # pragma: no cover - depends on the environment
    raise ImportError("mbs.torch needs PyTorch: pip install torch") from error

from mbs.torch.loss import S3Loss, S3LossOutput, photometric_map, ssim, warp_to_reference
from mbs.torch.schedules import cosine_momentum, ema_update_, sequence_weights
from mbs.torch.views import LEFT, RIGHT, mirror_left, predict

__all__ = [
    "LEFT",
    "RIGHT",
    "S3Loss",
    "S3LossOutput",
    "cosine_momentum",
    "ema_update_",
    "mirror_left",
    "photometric_map",
    "predict",
    "sequence_weights",
    "ssim",
    "warp_to_reference",
]
