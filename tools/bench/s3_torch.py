#!/usr/bin/env python3
"""PyTorch port of mbs-train's S3 training step, for benchmarking only.

The same network as `CostVolumeNet` (crates/mbs-train/src/backbone/
cost_volume.rs) and the same step as `S3Trainer::step` (src/step.rs), op for
op, so the amount of compute matches the Rust step (results are not meant to
be bit-identical):

- network: conv3x3/2 3->f/2, ReLU, conv3x3/2 f/2->f, ReLU, conv3x3 f->f
  (shared by both images, run as one batch of 2B); mean-centred cosine
  correlation over D/4 candidates (target features padded on the left,
  one multiply-and-channel-sum per candidate); conv3x3 (D/4+f)->h, ReLU,
  conv3x3 h->h, ReLU, conv3x3 h->D/4, plus 10 x the correlation; softmax
  over candidates, soft-argmin x 4, bilinear upsampling to full size as two
  matrix products with PyTorch's align_corners=False weights (upsample.rs);
- step: teacher forward under no_grad on the clean pair, student forward on
  the (here un-augmented) pair, left-side items mirrored in and out; the S3
  loss of src/losses: photometric maps 0.85 (1 - SSIM)/2 + 0.15 L1 (7x7 box
  SSIM with reflection padding, box sums by cumulative sums as
  photometric.rs; `--ssim-pool avgpool` uses F.avg_pool2d instead) of the
  warped and the un-warped targets (linear interpolation along x, border
  clamping), validity masks (P < 0.1 and P < P_identity), weight map A with
  omega 2, mean(A |d_s - r d_t|) + 10 mean(M_s P_s) + 0.01 edge-aware
  smoothness; backward; global-norm clipping to 1.0; Adam (burn's defaults:
  betas 0.9/0.999, eps 1e-5) at the one-cycle learning rate; EMA update of
  the teacher at the cosine momentum.

Run alone it prints one JSON line like the Rust example `step_time`:
    python3 tools/bench/s3_torch.py --batch 2 --height 256 --width 512 \\
        --max-disparity 128 --steps 5 --warmup 2 --threads 2

`--device cuda` runs it on a GPU: the network, batch and loss on the
device, autocast and the grad scaler on its type, timers synchronised with
the device, and the peak GPU memory (`torch.cuda.max_memory_allocated`)
beside the process's peak RSS.
"""

import argparse
import copy
import json
import math
import resource
import sys
import time

try:
    import torch
    import torch.nn.functional as F
    from torch import nn
except ImportError:  # pragma: no cover - message for people without torch
    sys.exit("s3_torch.py needs PyTorch: pip install torch")

RIGHT, LEFT = "right", "left"


# --------------------------------------------------------------------------
# Network (backbone/cost_volume.rs, backbone/upsample.rs, backbone/mod.rs)


def interpolation_matrix(n_out, n_in):
    """[n_out, n_in] 1-D linear interpolation, align_corners=False (upsample.rs)."""
    matrix = torch.zeros(n_out, n_in)
    scale = n_in / n_out
    for i in range(n_out):
        source = max((i + 0.5) * scale - 0.5, 0.0)
        left = min(int(math.floor(source)), n_in - 1)
        right = min(left + 1, n_in - 1)
        weight = source - left
        matrix[i, left] += 1.0 - weight
        matrix[i, right] += weight
    return matrix


_MATRICES = {}


def synchronize(device):
    """Waits for the device's queued work (a no-op on the CPU), so that a
    timer read after it measures the work itself."""
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def upsample_bilinear(maps, height, width):
    """U_h maps U_w^T, as upsample.rs (matrices cached per size and device)."""
    _, _, h, w = maps.shape
    key = (height, h, width, w, maps.device, maps.dtype)
    if key not in _MATRICES:
        rows = interpolation_matrix(height, h).to(maps)
        _MATRICES[key] = (rows, interpolation_matrix(width, w).t().contiguous().to(maps))
    rows, cols_t = _MATRICES[key]
    return rows @ maps @ cols_t


class CostVolumeNet(nn.Module):
    def __init__(self, max_disparity=64, features=16, hidden=32, correlation_weight=10.0):
        super().__init__()
        if max_disparity < 4 or max_disparity % 4:
            raise ValueError(f"max_disparity {max_disparity}: a positive multiple of 4")

        def conv(cin, cout, stride):
            return nn.Conv2d(cin, cout, 3, stride=stride, padding=1)

        candidates = max_disparity // 4
        self.stem = conv(3, features // 2, 2)
        self.down = conv(features // 2, features, 2)
        self.refine = conv(features, features, 1)
        self.aggregate_in = conv(candidates + features, hidden, 1)
        self.aggregate_mid = conv(hidden, hidden, 1)
        self.logits = conv(hidden, candidates, 1)
        self.candidates = candidates
        self.correlation_weight = correlation_weight
        self.register_buffer("candidate_values", torch.arange(candidates, dtype=torch.float32).view(1, -1, 1, 1))

    def features(self, images):
        x = F.relu(self.stem(images * 2.0 - 1.0))
        x = F.relu(self.down(x))
        return self.refine(x)

    def correlation(self, left, right):
        width = left.shape[3]

        def unit(features):
            centred = features - features.mean(dim=(2, 3), keepdim=True)
            norm = (centred * centred).sum(dim=1, keepdim=True).sqrt() + 1e-6
            return centred / norm

        left, right = unit(left), unit(right)
        shift = self.candidates - 1
        padded = F.pad(right, (shift, 0, 0, 0))
        slices = [(left * padded[..., shift - d : shift - d + width]).sum(dim=1, keepdim=True) for d in range(self.candidates)]
        return torch.cat(slices, 1)

    def forward(self, reference, target):
        batch, _, height, width = reference.shape
        features = self.features(torch.cat([reference, target], 0))
        left, right = features[:batch], features[batch:]
        volume = self.correlation(left, right)
        x = F.relu(self.aggregate_in(torch.cat([volume, left], 1)))
        x = F.relu(self.aggregate_mid(x))
        logits = self.logits(x) + volume * self.correlation_weight
        probabilities = torch.softmax(logits, dim=1)
        quarter = (probabilities * self.candidate_values).sum(dim=1, keepdim=True) * 4.0
        return upsample_bilinear(quarter, height, width)


def mirror_left(tensor, sides):
    """Flips along x the items whose target is on the left (mirror.rs)."""
    if all(side == RIGHT for side in sides):
        return tensor
    if all(side == LEFT for side in sides):
        return tensor.flip(-1)
    return torch.cat([item.flip(-1) if side == LEFT else item for item, side in zip(tensor.split(1, 0), sides)], 0)


def predict(net, reference, target, sides):
    return mirror_left(net(mirror_left(reference, sides), mirror_left(target, sides)), sides)


# --------------------------------------------------------------------------
# Loss (losses/*.rs, mask.rs)

C1 = 0.01**2
C2 = 0.03**2


def window_sums(tensor, dim, window):
    outputs = tensor.shape[dim] + 1 - window
    zero_shape = list(tensor.shape)
    zero_shape[dim] = 1
    prefix = torch.cat([tensor.new_zeros(zero_shape), tensor.cumsum(dim)], dim)
    return prefix.narrow(dim, window, outputs) - prefix.narrow(dim, 0, outputs)


def window_means(tensor, window, pool):
    """Means over every window x window box that fits (no padding)."""
    if pool == "avgpool":
        return F.avg_pool2d(tensor, window, stride=1)
    return window_sums(window_sums(tensor, 2, window), 3, window) / (window * window)


def ssim(x, y, window, pool):
    # As photometric.rs: the centred images are reflection-padded once and
    # each moment is filtered on its own.
    pad = window // 2
    x = F.pad(x - 0.5, (pad, pad, pad, pad), mode="reflect")
    y = F.pad(y - 0.5, (pad, pad, pad, pad), mode="reflect")
    mx, my = window_means(x, window, pool), window_means(y, window, pool)
    sigma_x = window_means(x * x, window, pool) - mx * mx
    sigma_y = window_means(y * y, window, pool) - my * my
    sigma_xy = window_means(x * y, window, pool) - mx * my
    mu_x, mu_y = mx + 0.5, my + 0.5
    numerator = (mu_x * mu_y * 2.0 + C1) * (sigma_xy * 2.0 + C2)
    denominator = (mu_x * mu_x + mu_y * mu_y + C1) * (sigma_x + sigma_y + C2)
    return numerator / denominator


def photometric_map(reference, reconstructed, alpha, window, pool):
    dissimilarity = ((1.0 - ssim(reference, reconstructed, window, pool)) / 2.0).clamp(0.0, 1.0)
    l1 = (reference - reconstructed).abs()
    return (dissimilarity * alpha + l1 * (1.0 - alpha)).mean(dim=1, keepdim=True)


def warp_to_reference(target, disparity, sides):
    """Samples target at x - d (right) / x + d (left), linear along x (warp.rs)."""
    batch, channels, height, width = target.shape
    columns = torch.arange(width, dtype=torch.float32, device=target.device).view(1, 1, 1, width)
    signs = torch.tensor([1.0 if side == RIGHT else -1.0 for side in sides], device=target.device).view(batch, 1, 1, 1)
    x = (columns - disparity * signs).clamp(0.0, width - 1)
    left = x.detach().floor().clamp(max=width - 2)
    weight = x - left
    left = left.long().expand(batch, channels, height, width)
    left_values = target.gather(3, left)
    right_values = target.gather(3, left + 1)
    return left_values * (1.0 - weight) + right_values * weight


def validity_mask(photometric, identity, tau):
    photometric = photometric.detach()
    return (photometric < tau).float() * (photometric < identity.detach()).float()


def edge_aware_smoothness(disparity, image):
    def term(dim):
        length = disparity.shape[dim]
        step = lambda t: t.narrow(dim, 1, length - 1) - t.narrow(dim, 0, length - 1)
        return (step(disparity).abs() * (-step(image).abs().mean(dim=1, keepdim=True)).exp()).mean()

    return term(3) + term(2)


class S3Loss:
    def __init__(self, tau=0.1, omega=2.0, lambda_p=10.0, lambda_s_ratio=0.001, alpha=0.85, ssim_window=7, pool="cumsum"):
        self.tau, self.omega, self.lambda_p = tau, omega, lambda_p
        self.lambda_s = lambda_s_ratio * lambda_p
        self.alpha, self.window, self.pool = alpha, ssim_window, pool

    def photometric_pair(self, reference, target, disparity, sides):
        identity = photometric_map(reference, target, self.alpha, self.window, self.pool)
        warped = warp_to_reference(target, disparity, sides)
        return photometric_map(reference, warped, self.alpha, self.window, self.pool), identity

    def __call__(self, reference, student_target, teacher_target, d_s, d_t, student_sides, teacher_sides, ratios):
        p_s, id_s = self.photometric_pair(reference, student_target, d_s, student_sides)
        m_s = validity_mask(p_s, id_s, self.tau)
        total = (m_s * p_s).mean() * self.lambda_p
        d_t = d_t.detach()
        p_t, id_t = self.photometric_pair(reference, teacher_target, d_t, teacher_sides)
        m_t = validity_mask(p_t, id_t, self.tau)
        a = m_t * (m_s * (1.0 - self.omega) + self.omega)
        r = torch.tensor(ratios, dtype=torch.float32, device=reference.device).view(-1, 1, 1, 1)
        total = total + (a * (d_s - d_t * r).abs()).mean()
        return total + edge_aware_smoothness(d_s, reference) * self.lambda_s


# --------------------------------------------------------------------------
# Schedules (schedule.rs) and the step (step.rs)


def one_cycle_lr(step, max_lr, total_steps, pct_start=0.01, div_factor=25.0, final_div_factor=1e4):
    initial = max_lr / div_factor
    low = initial / final_div_factor
    warmup_end = pct_start * total_steps - 1.0
    last = float(total_steps - 1)
    step = min(float(step), last)
    if step <= warmup_end:
        pct = step / warmup_end if warmup_end > 0 else 1.0
        return initial + (max_lr - initial) * pct
    start = max(warmup_end, 0.0)
    return max_lr + (low - max_lr) * (step - start) / (last - start)


def cosine_momentum(step, base, total_steps):
    progress = min(step, total_steps) / total_steps
    return 1.0 - (1.0 - base) * (math.cos(math.pi * progress) + 1.0) / 2.0


class S3Trainer:
    def __init__(self, student, max_lr=2e-4, total_steps=100, ema_base=0.996, grad_clip_norm=1.0, loss=None,
                 precision="f32"):
        self.student = student
        self.device = next(student.parameters()).device
        # Mixed precision as mbs's trainer.precision: the networks under
        # autocast, the loss in f32, f16 with a GradScaler, both on the
        # student's device type.
        self.autocast_dtype = {"f32": None, "bf16": torch.bfloat16, "f16": torch.float16}[precision]
        self.scaler = torch.amp.GradScaler(self.device.type) if precision == "f16" else None
        self.teacher = copy.deepcopy(student).requires_grad_(False)
        self.loss = loss or S3Loss()
        self.optimizer = torch.optim.Adam(student.parameters(), lr=max_lr, betas=(0.9, 0.999), eps=1e-5)
        self.max_lr, self.total_steps = max_lr, total_steps
        self.ema_base, self.grad_clip_norm = ema_base, grad_clip_norm
        self.step_index = 0
        self.times = None  # phase -> accumulated ms, when timing phases

    def _mark(self, phase, start):
        if self.times is not None:
            synchronize(self.device)
            now = time.perf_counter()
            self.times[phase] = self.times.get(phase, 0.0) + (now - start) * 1e3
            return now
        return start

    def step(self, batch):
        t = time.perf_counter()
        autocast = torch.autocast(self.device.type, dtype=self.autocast_dtype, enabled=self.autocast_dtype is not None)
        with torch.no_grad(), autocast:
            d_t = predict(self.teacher, batch["reference"], batch["teacher_target"], batch["teacher_sides"])
        d_t = d_t.float()
        t = self._mark("teacher_forward", t)
        with autocast:
            d_s = predict(self.student, batch["augmented_reference"], batch["augmented_target"], batch["student_sides"])
        d_s = d_s.float()
        t = self._mark("student_forward", t)
        total = self.loss(
            batch["reference"], batch["student_target"], batch["teacher_target"], d_s, d_t,
            batch["student_sides"], batch["teacher_sides"], batch["ratios"],
        )
        loss = total.item()
        t = self._mark("loss", t)
        self.optimizer.zero_grad(set_to_none=True)
        (total if self.scaler is None else self.scaler.scale(total)).backward()
        t = self._mark("backward", t)
        if self.scaler is not None:
            self.scaler.unscale_(self.optimizer)
        grad_norm = torch.nn.utils.clip_grad_norm_(self.student.parameters(), self.grad_clip_norm).item()
        for group in self.optimizer.param_groups:
            group["lr"] = one_cycle_lr(self.step_index, self.max_lr, self.total_steps)
        if self.scaler is None:
            self.optimizer.step()
        else:
            self.scaler.step(self.optimizer)
            self.scaler.update()
        momentum = cosine_momentum(self.step_index, self.ema_base, self.total_steps)
        with torch.no_grad():
            for teacher, student in zip(self.teacher.parameters(), self.student.parameters()):
                teacher.mul_(momentum).add_(student, alpha=1.0 - momentum)
        self._mark("clip_adam_ema", t)
        self.step_index += 1
        return loss, grad_norm


def make_batch(batch, height, width, device="cpu"):
    image = lambda: torch.rand(batch, 3, height, width).to(device)
    reference, student_target, teacher_target = image(), image(), image()
    return {
        "reference": reference,
        "student_target": student_target,
        "teacher_target": teacher_target,
        "augmented_reference": reference,
        "augmented_target": student_target,
        "student_sides": [RIGHT if i % 2 == 0 else LEFT for i in range(batch)],
        "teacher_sides": [RIGHT] * batch,
        "ratios": [1.0 if i % 2 == 0 else 0.5 for i in range(batch)],
    }


def rss_mib(field):
    """VmRSS / VmHWM of /proc/self/status in MiB (None off Linux)."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batch", type=int, default=2)
    parser.add_argument("--height", type=int, default=256)
    parser.add_argument("--width", type=int, default=512)
    parser.add_argument("--max-disparity", type=int, default=128)
    parser.add_argument("--steps", type=int, default=5)
    parser.add_argument("--warmup", type=int, default=2)
    parser.add_argument("--features", type=int, default=16)
    parser.add_argument("--hidden", type=int, default=32)
    parser.add_argument("--seed", type=int, default=42)
    parser.add_argument("--threads", type=int, default=2, help="torch.set_num_threads")
    parser.add_argument("--ssim-pool", choices=["cumsum", "avgpool"], default="cumsum")
    parser.add_argument("--breakdown", action="store_true", help="also time each phase over --steps more steps")
    parser.add_argument("--precision", choices=["f32", "bf16", "f16"], default="f32",
                        help="the networks under torch.autocast in this format (f16 with a GradScaler)")
    parser.add_argument("--device", default="cpu", help="torch device: cpu, cuda, cuda:1, ...")
    args = parser.parse_args()
    if min(args.batch, args.height, args.width, args.steps) < 1 or args.warmup < 0:
        parser.error("batch, height, width and steps must be at least 1, warmup at least 0")

    device = torch.device(args.device)
    if device.type == "cuda" and not torch.cuda.is_available():
        parser.error(f"--device {args.device}: PyTorch sees no CUDA device")
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    net = CostVolumeNet(args.max_disparity, args.features, args.hidden).to(device)
    total_steps = args.warmup + 2 * args.steps
    trainer = S3Trainer(net, total_steps=total_steps, loss=S3Loss(pool=args.ssim_pool), precision=args.precision)
    batch = make_batch(args.batch, args.height, args.width, device)
    rss_setup = rss_mib("VmRSS")
    for _ in range(args.warmup):
        trainer.step(batch)
    if device.type == "cuda":
        torch.cuda.reset_peak_memory_stats(device)
    synchronize(device)
    start = time.perf_counter()
    loss = float("nan")
    for _ in range(args.steps):
        loss, _ = trainer.step(batch)
    synchronize(device)
    ms_per_step = (time.perf_counter() - start) * 1e3 / args.steps
    out = {
        "framework": "torch",
        "device": str(device),
        "batch": args.batch,
        "height": args.height,
        "width": args.width,
        "max_disparity": args.max_disparity,
        "precision": args.precision,
        "ms_per_step": round(ms_per_step, 2),
        "peak_rss_mib": None,
        "steps": args.steps,
        "warmup": args.warmup,
        "torch_threads": torch.get_num_threads(),
        "torch_version": torch.__version__,
        "ssim_pool": args.ssim_pool,
        "rss_before_steps_mib": None if rss_setup is None else round(rss_setup, 1),
        "loss": loss if math.isfinite(loss) else None,
    }
    if args.breakdown:
        trainer.times = {}
        for _ in range(args.steps):
            trainer.step(batch)
        out["breakdown_ms"] = {k: round(v / args.steps, 2) for k, v in trainer.times.items()}
    peak = rss_mib("VmHWM")
    if peak is None:  # ru_maxrss is in KiB on Linux
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    out["peak_rss_mib"] = round(peak, 1)
    if device.type == "cuda":
        out["peak_gpu_mib"] = round(torch.cuda.max_memory_allocated(device) / 2**20, 1)
        out["gpu"] = torch.cuda.get_device_name(device)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
