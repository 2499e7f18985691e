"""Parity fixtures of RAFT-Stereo from the official PyTorch code.

Run by hand where PyTorch is installed (never in CI):

    git clone https://github.com/princeton-vl/RAFT-Stereo /tmp/RAFT-Stereo
    pip install torch opt_einsum scipy safetensors
    python3 tools/parity/raft_stereo_fixtures.py --official /tmp/RAFT-Stereo

For each small configuration below it builds the official `RAFTStereo`,
fills its state dict with the seeded weights of `seeded_weights.py` (which
mbs reproduces bit for bit), runs a fixed pair of batch 2 in eval mode
(batch norm frozen, as the official training does) and writes
`testdata/parity/raft_stereo_<name>.safetensors`: the input pair in [0, 1],
the disparity (-flow) of every iteration, and as metadata the configuration
and every state-dict key with its shape. It also writes a small `.pth` (a
part of one state dict, with DataParallel's `module.` prefix) that the
loader tests read.

`--check-export FILE --run-config RUN/config.json --left L --right R
--mbs-disparity D.pfm` instead checks an export of mbs against mbs itself:
it builds the official module with the run's network.raft_stereo settings,
loads the weights that `mbs-tool export` wrote (strict: every key, no
other), predicts the pair with the run's test iterations and compares with
the disparity that `mbs-tool predict --backbone raft-stereo --weights FILE`
wrote for the same pair.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from seeded_weights import seed_module  # noqa: E402

CONFIGS = {
    # Three GRU levels at 1/4 resolution, batch-norm context (the official defaults, narrower).
    "three_levels": dict(hidden_dims=[32] * 3, n_gru_layers=3, corr_levels=2, corr_radius=2,
                         n_downsample=2, context_norm="batch", slow_fast_gru=False, iters=3),
    # Two GRU levels at 1/8 resolution, instance-norm context, slow-fast updates.
    "two_levels_slow_fast": dict(hidden_dims=[24] * 3, n_gru_layers=2, corr_levels=3, corr_radius=1,
                                 n_downsample=3, context_norm="instance", slow_fast_gru=True, iters=2),
}
HEIGHT, WIDTH = 64, 96


def args_for(config):
    return argparse.Namespace(
        hidden_dims=config["hidden_dims"], n_gru_layers=config["n_gru_layers"],
        corr_levels=config["corr_levels"], corr_radius=config["corr_radius"],
        n_downsample=config["n_downsample"], context_norm=config["context_norm"],
        slow_fast_gru=config["slow_fast_gru"], shared_backbone=False,
        corr_implementation="reg", mixed_precision=False)


def input_pair():
    """A smooth random texture and its copy shifted by 3 px (batch item 0) or 5 px (item 1)."""
    rng = np.random.default_rng(7)
    pairs = []
    for shift in (3, 5):
        coarse = rng.random((3, HEIGHT // 4 + 1, WIDTH // 4 + 8))
        fine = np.kron(coarse, np.ones((1, 4, 4)))[:, :HEIGHT, : WIDTH + 16]
        fine = 0.7 * fine + 0.3 * rng.random(fine.shape)
        left = fine[:, :, 8 : 8 + WIDTH]
        right = fine[:, :, 8 + shift : 8 + shift + WIDTH]
        pairs.append((left, right))
    left = np.stack([p[0] for p in pairs]).astype(np.float32)
    right = np.stack([p[1] for p in pairs]).astype(np.float32)
    return left, right


def run(model, left, right, iters):
    import torch

    with torch.no_grad():
        flows = model(torch.from_numpy(left) * 255.0, torch.from_numpy(right) * 255.0, iters=iters)
    return [(-f).numpy().astype(np.float32) for f in flows]


def build(official, name):
    sys.path.insert(0, str(official))
    from core.raft_stereo import RAFTStereo

    config = CONFIGS[name]
    model = RAFTStereo(args_for(config)).eval()
    return config, model


def read_pfm(path):
    """A one-channel PFM as a top-to-bottom float32 array."""
    with open(path, "rb") as f:
        assert f.readline().strip() == b"Pf", f"{path}: not a one-channel PFM"
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    return np.flipud(data.reshape(height, width)).astype(np.float32)


def add_check_export_arguments(parser):
    """The flags of `--check-export`, shared by both fixture scripts."""
    parser.add_argument("--check-export", type=Path, help="safetensors exported by mbs")
    parser.add_argument("--run-config", type=Path, help="the exported run's config.json")
    parser.add_argument("--left", type=Path, help="left image of the checked pair")
    parser.add_argument("--right", type=Path, help="right image of the checked pair")
    parser.add_argument("--mbs-disparity", type=Path, help="mbs's prediction of the pair (PFM)")


def read_rgb(path):
    """An image as a [1, 3, H, W] float tensor in [0, 255], RGB order."""
    import cv2
    import torch

    rgb = cv2.imread(str(path), cv2.IMREAD_COLOR)[:, :, ::-1].astype(np.float32)
    return torch.from_numpy(rgb.copy()).permute(2, 0, 1)[None]


def report_export(args, network, official):
    """Compares the official prediction with mbs's PFM and exits 0 within 1e-3 px."""
    worst = float(np.abs(official - read_pfm(args.mbs_disparity)).max())
    print(f"{args.check_export}: loads strictly into the official {network}; largest difference to mbs's "
          f"prediction {worst:.2e} px (disparities {official.min():.1f} to {official.max():.1f} px)")
    sys.exit(0 if worst < 1e-3 else 1)


def check_export(args):
    import torch
    from safetensors.torch import load_file

    settings = json.loads(args.run_config.read_text())["network"]["raft_stereo"]
    config = dict(hidden_dims=[settings["hidden_dim"]] * 3, n_gru_layers=settings["gru_levels"],
                  corr_levels=settings["corr_levels"], corr_radius=settings["corr_radius"],
                  n_downsample=settings["n_downsample"], context_norm=settings["context_norm"],
                  slow_fast_gru=settings["slow_fast_gru"])
    sys.path.insert(0, str(args.official))
    from core.raft_stereo import RAFTStereo

    model = RAFTStereo(args_for(config)).eval()
    model.load_state_dict(load_file(str(args.check_export)), strict=True)

    with torch.no_grad():
        flow = model(read_rgb(args.left), read_rgb(args.right), iters=settings["test_iters"])[-1]
    report_export(args, "RAFTStereo", (-flow)[0, 0].numpy())


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--official", required=True, type=Path, help="checkout of princeton-vl/RAFT-Stereo")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[2] / "testdata" / "parity")
    add_check_export_arguments(parser)
    args = parser.parse_args()

    import torch
    from safetensors.numpy import save_file
    from safetensors.torch import load_file

    torch.manual_seed(0)
    if args.check_export:
        check_export(args)
        return

    args.out.mkdir(parents=True, exist_ok=True)
    left, right = input_pair()
    for name in CONFIGS:
        config, model = build(args.official, name)
        seed_module(model)
        outputs = run(model, left, right, config["iters"])
        tensors = {"left": left, "right": right}
        tensors.update({f"disparity_{i}": o for i, o in enumerate(outputs)})
        shapes = {k: list(v.shape) for k, v in model.state_dict().items()}
        metadata = {"config": json.dumps(config), "state_dict": json.dumps(shapes)}
        path = args.out / f"raft_stereo_{name}.safetensors"
        save_file(tensors, str(path), metadata=metadata)
        last = outputs[-1]
        print(f"{path}: {len(shapes)} keys, final disparity mean {last.mean():.3f} px "
              f"(item means {last[0].mean():.3f}, {last[1].mean():.3f})")
        if name == "three_levels":
            part = {f"module.{k}": v for k, v in model.state_dict().items() if k.startswith("context_zqr_convs.")}
            torch.save(part, args.out / "raft_stereo_part.pth")


if __name__ == "__main__":
    main()
