"""The GPU check (tools/gpu) on the CPU, so that it cannot rot before a GPU
runs it: `run.py --device cpu --small` goes through every phase with the
mbs-tool of this tree (the official code's parts are recorded as not run:
the repository never holds that code; the same binary stands in for the
autotune build), and `prepare.sh` assembles its folder, compresses the
binaries losslessly and refuses a folder over the limit (32 MiB with one
binary, 48 MiB with the autotune build too), leaving nothing behind.
"""

import json
import lzma
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MBS_TOOL = os.environ.get("MBS_TOOL", str(ROOT / "target" / "debug" / "mbs-tool"))
PHASES = ["environment", "probe", "compact", "raft-stereo", "igev", "precision", "predict", "autotune"]


def test_the_gpu_check_runs_every_phase_on_the_cpu(tmp_path: Path) -> None:
    out = tmp_path / "results"
    done = subprocess.run(
        [
            sys.executable,
            str(ROOT / "tools" / "gpu" / "run.py"),
            "--device",
            "cpu",
            "--small",
            "--binary",
            MBS_TOOL,
            "--autotune-binary",
            MBS_TOOL,
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "GPU check on cpu (small)" in done.stdout
    results = json.loads((out / "results.json").read_text())
    assert list(results["phases"]) == PHASES
    for name, phase in results["phases"].items():
        assert phase["status"] == "ok", (name, phase)
    figures = {name: phase["figures"] for name, phase in results["phases"].items()}
    # The CPU against itself: the same steps, bit for bit.
    assert figures["compact"]["loss_relative_error"] == 0.0
    assert figures["compact"]["grad_norm_relative_error"] == 0.0
    assert len(figures["compact"]["steps"]) == 4
    for network in ("raft-stereo", "igev"):
        mbs = figures[network]["mbs"]
        assert mbs["ms_per_step"] > 0 and mbs["first_step_ms"] > 0 and mbs["loss"] > 0, mbs
        assert "not_run" in figures[network]["official"] or figures[network]["official"]["ms_per_step"] > 0
    for fmt in ("bf16", "f16"):
        assert figures["precision"][fmt]["mbs"]["ms_per_step"] > 0
    assert figures["predict"]["mbs_device_vs_cpu_mean_px"] == 0.0
    assert (out / "logs" / "raft-stereo.log").read_text().startswith("$ ")
    for network in ("raft-stereo", "igev"):
        tuned = figures["autotune"][network]
        assert tuned["autotune"]["ms_per_step"] > 0 and tuned["default"] == figures[network]["mbs"], tuned
        assert tuned["autotune_over_default"] > 0, tuned
    assert (out / "logs" / "igev-autotune.log").is_file()


def test_prepare_assembles_the_folder_and_refuses_one_over_the_limit(tmp_path: Path) -> None:
    binary = tmp_path / "mbs-tool"
    binary.write_bytes(bytes(range(256)) * 4096)
    tuned = tmp_path / "mbs-tool-autotune"
    tuned.write_bytes(bytes(range(255, -1, -1)) * 4096)
    prepare = ["bash", str(ROOT / "tools" / "gpu" / "prepare.sh")]
    folder = tmp_path / "gpu-check"
    done = subprocess.run(
        [*prepare, str(folder), "--binary", str(binary), "--autotune-binary", str(tuned)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"{folder} is " in done.stdout and "MiB" in done.stdout
    assert lzma.decompress((folder / "mbs-tool.xz").read_bytes()) == binary.read_bytes()
    assert lzma.decompress((folder / "mbs-tool-autotune.xz").read_bytes()) == tuned.read_bytes()
    for part in [
        "run.py",
        "official_predict.py",
        "bench/official_step_vs_torch.py",
        "bench/s3_torch.py",
        "bench/train_step_vs_torch.py",
        "data/pair/view1.png",
        "data/pair/view2.png",
    ]:
        assert (folder / part).is_file(), part
    # Random bytes do not compress: 33 MiB of them is over one binary's
    # limit, and 2 x 25 MiB over two binaries'.
    for size_mib, extra, limit in [(33, ["--no-autotune"], 32), (25, ["--autotune-binary", str(tuned)], 48)]:
        binary.write_bytes(os.urandom(size_mib << 20))
        tuned.write_bytes(os.urandom(size_mib << 20))
        big = tmp_path / "too-big"
        done = subprocess.run(
            [*prepare, str(big), "--binary", str(binary), *extra], capture_output=True, text=True, timeout=600
        )
        assert done.returncode == 1, done.stdout + done.stderr
        assert f"over the {limit} MiB limit" in done.stderr
        assert not big.exists() and not Path(f"{big}.partial").exists()
