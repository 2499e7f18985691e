"""The GPU check (tools/gpu) on the CPU, so that it cannot rot before a GPU
runs it: `run.py --device cpu --small` goes through every phase with the
mbs-tool of this tree (the official code's parts are recorded as not run:
the repository never holds that code), and `prepare.sh` assembles its
folder, compresses the binary losslessly and refuses a folder over the
32 MiB limit, leaving nothing behind.
"""

import json
import lzma
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MBS_TOOL = os.environ.get("MBS_TOOL", str(ROOT / "target" / "debug" / "mbs-tool"))
PHASES = ["environment", "probe", "compact", "raft-stereo", "igev", "precision", "predict"]


def test_the_gpu_check_runs_every_phase_on_the_cpu(tmp_path):
    out = tmp_path / "results"
    done = subprocess.run([sys.executable, str(ROOT / "tools" / "gpu" / "run.py"), "--device", "cpu", "--small",
                           "--binary", MBS_TOOL, "--out", str(out)], capture_output=True, text=True, timeout=1200)
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


def test_prepare_assembles_the_folder_and_refuses_one_over_the_limit(tmp_path):
    binary = tmp_path / "mbs-tool"
    binary.write_bytes(bytes(range(256)) * 4096)
    folder = tmp_path / "gpu-check"
    done = subprocess.run(["bash", str(ROOT / "tools" / "gpu" / "prepare.sh"), str(folder), "--binary", str(binary)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"{folder} is " in done.stdout and "MiB" in done.stdout
    assert lzma.decompress((folder / "mbs-tool.xz").read_bytes()) == binary.read_bytes()
    for part in ["run.py", "official_predict.py", "bench/official_step_vs_torch.py", "bench/s3_torch.py",
                 "bench/train_step_vs_torch.py", "data/pair/view1.png", "data/pair/view2.png"]:
        assert (folder / part).is_file(), part
    # Random bytes do not compress: 33 MiB of them is over the limit.
    binary.write_bytes(os.urandom(33 << 20))
    big = tmp_path / "too-big"
    done = subprocess.run(["bash", str(ROOT / "tools" / "gpu" / "prepare.sh"), str(big), "--binary", str(binary)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "over the 32 MiB limit" in done.stderr
    assert not big.exists() and not Path(f"{big}.partial").exists()
