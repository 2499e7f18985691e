"""Parity fixtures of IGEV-Stereo from the official PyTorch code.

Run by hand where PyTorch is installed (never in CI):

    git clone https://github.com/gangweiX/IGEV /tmp/IGEV
    pip install torch "timm==0.5.4" opt_einsum scipy safetensors
    python3 tools/parity/igev_stereo_fixtures.py --official /tmp/IGEV/IGEV-Stereo

timm 0.5.4 is the version the official code was written for (later
versions fold MobileNetV2's activation into its batch norm). The feature
encoder is built with `pretrained=False` (nothing is downloaded): every
tensor of the state dict then gets the seeded weights of
`seeded_weights.py`, which mbs reproduces bit for bit. For each small
configuration below, a fixed pair of batch 2 runs in eval mode (batch norm
on its running statistics) and `testdata/parity/igev_stereo_<name>.safetensors`
receives the pair in [0, 1], the initial disparity (`disparity_init`, from
the geometry encoding volume, upsampled), the disparity of every iteration,
and as metadata the configuration and every state-dict key with its shape.

`--check-export FILE --run-config RUN/config.json --left L --right R
--mbs-disparity D.pfm` instead loads weights that `mbs-tool export` wrote
into the official module (strict) with the run's network.igev settings and
compares its prediction of the pair with the one `mbs-tool predict
--backbone igev --weights FILE` wrote (sides multiples of 32).
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from raft_stereo_fixtures import add_check_export_arguments, input_pair, read_rgb, report_export  # noqa: E402
from seeded_weights import seed_module  # noqa: E402

CONFIGS = {
    # Three GRU levels (the official default), narrower, a 64 px range.
    "three_levels": dict(hidden_dims=[32] * 3, n_gru_layers=3, corr_levels=2, corr_radius=2,
                         max_disp=64, iters=3),
    # Two GRU levels, radius 1.
    "two_levels": dict(hidden_dims=[24] * 3, n_gru_layers=2, corr_levels=2, corr_radius=1,
                       max_disp=64, iters=2),
}


def build(official, config):
    import timm

    create = timm.create_model
    timm.create_model = lambda name, pretrained=False, **kw: create(name, pretrained=False, **kw)
    sys.path.insert(0, str(official))
    from core.igev_stereo import IGEVStereo

    args = argparse.Namespace(hidden_dims=config["hidden_dims"], n_gru_layers=config["n_gru_layers"],
                              corr_levels=config["corr_levels"], corr_radius=config["corr_radius"],
                              n_downsample=2, max_disp=config["max_disp"], mixed_precision=False,
                              precision_dtype="float32")
    return IGEVStereo(args).eval()


def check_export(args):
    import torch
    from safetensors.torch import load_file

    settings = json.loads(args.run_config.read_text())["network"]["igev"]
    config = dict(hidden_dims=[settings["hidden_dim"]] * 3, n_gru_layers=settings["gru_levels"],
                  corr_levels=settings["corr_levels"], corr_radius=settings["corr_radius"],
                  max_disp=settings["max_disp"])
    model = build(args.official, config)
    model.load_state_dict(load_file(str(args.check_export)), strict=True)

    with torch.no_grad():
        official = model(read_rgb(args.left), read_rgb(args.right), iters=settings["test_iters"], test_mode=True)
    report_export(args, "IGEVStereo", official[0, 0].numpy())


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--official", required=True, type=Path, help="the IGEV-Stereo folder of gangweiX/IGEV")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[2] / "testdata" / "parity")
    add_check_export_arguments(parser)
    args = parser.parse_args()
    if args.check_export:
        check_export(args)
        return

    import torch
    from safetensors.numpy import save_file

    torch.manual_seed(0)
    args.out.mkdir(parents=True, exist_ok=True)
    left, right = input_pair()
    for name, config in CONFIGS.items():
        model = build(args.official, config)
        seed_module(model)
        # test_mode=False returns the upsampled initial disparity and every
        # iteration; spx (the training-time upsampler of the initial
        # disparity) runs only then.
        model.train(False)
        with torch.no_grad():
            init, predictions = model(torch.from_numpy(left) * 255.0, torch.from_numpy(right) * 255.0,
                                      iters=config["iters"], test_mode=False)
        tensors = {"left": left, "right": right, "disparity_init": init.numpy().astype(np.float32)}
        tensors.update({f"disparity_{i}": p.numpy().astype(np.float32) for i, p in enumerate(predictions)})
        shapes = {k: list(v.shape) for k, v in model.state_dict().items()}
        metadata = {"config": json.dumps(config), "state_dict": json.dumps(shapes)}
        path = args.out / f"igev_stereo_{name}.safetensors"
        save_file(tensors, str(path), metadata=metadata)
        last = predictions[-1].numpy()
        print(f"{path}: {len(shapes)} keys, initial disparity mean {init.mean():.3f} px, "
              f"final {last.mean():.3f} px (std {last.std():.3f})")


if __name__ == "__main__":
    main()
