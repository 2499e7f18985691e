"""The GPU check (tools/gpu) on the CPU, so that it cannot rot before a GPU
runs it: `run.py --device cpu --small` goes through every phase with the
mbs-tool of this tree (the official code's parts are recorded as not run:
the repository never holds that code; the same binary stands in for the
autotune build), and `prepare.sh` assembles its folder, compresses the
binaries losslessly and refuses a folder over the limit (32 MiB with one
binary, 48 MiB with the autotune build too), leaving nothing behind.
Both delete only what they made: prepare.sh refuses an existing OUT (with
--force it replaces only a bundle of its own), never touches OUT.partial,
takes relative paths from the caller's folder and checks every input before
building; run.py unpacks its binaries under a temporary name and renames
them when complete, and refuses a broken archive in one line.
"""

from __future__ import annotations

import json
import lzma
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

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


# prepare.sh and run.py delete only what they made (issue 50).

PREPARE = ROOT / "tools" / "gpu" / "prepare.sh"
MARKER = ".mbs-gpu-bundle"


def prepare(*argv: str, cwd: Path | None = None, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["bash", str(PREPARE), *argv], capture_output=True, text=True, timeout=300, cwd=cwd, env=env)


def small_binary(path: Path, seed: int = 0) -> Path:
    path.write_bytes(bytes((seed + i) % 256 for i in range(256)) * 64)
    return path


def one_line(text: str) -> str:
    lines = text.strip().splitlines()
    assert len(lines) == 1, text
    return lines[0]


def test_prepare_refuses_an_existing_out_and_force_replaces_only_its_own_bundle(tmp_path: Path) -> None:
    binary = small_binary(tmp_path / "mbs-tool")
    users = tmp_path / "users-folder"
    users.mkdir()
    (users / "notes.txt").write_text("mine\n")
    (tmp_path / "users-file").write_text("mine too\n")
    (tmp_path / "users-link").symlink_to(users)
    for name in ["users-folder", "users-file", "users-link"]:
        for force in [[], ["--force"]]:
            done = prepare(str(tmp_path / name), *force, "--binary", str(binary), "--no-autotune")
            assert done.returncode == 2, (name, force, done.stdout + done.stderr)
            line = one_line(done.stderr)
            assert str(tmp_path / name) in line, line
            assert ("not a bundle prepare.sh made" in line) if force else ("already exists" in line), line
    assert (users / "notes.txt").read_text() == "mine\n" and sorted(p.name for p in users.iterdir()) == ["notes.txt"]
    assert (tmp_path / "users-file").read_text() == "mine too\n"
    assert (tmp_path / "users-link").is_symlink()

    bundle = tmp_path / "bundle"
    assert prepare(str(bundle), "--binary", str(binary), "--no-autotune").returncode == 0
    assert (bundle / MARKER).is_file()
    done = prepare(str(bundle), "--binary", str(binary), "--no-autotune")
    assert done.returncode == 2 and "already exists" in done.stderr, done.stderr
    # A link to a bundle is not the bundle: --force leaves it.
    (tmp_path / "bundle-link").symlink_to(bundle)
    done = prepare(str(tmp_path / "bundle-link"), "--force", "--binary", str(binary), "--no-autotune")
    assert done.returncode == 2 and "is a link" in done.stderr, done.stderr
    other = small_binary(tmp_path / "other", seed=7)
    done = prepare(str(bundle), "--force", "--binary", str(other), "--no-autotune")
    assert done.returncode == 0, done.stdout + done.stderr
    assert lzma.decompress((bundle / "mbs-tool.xz").read_bytes()) == other.read_bytes()
    assert (bundle / MARKER).is_file()
    # Nothing left beside it: no temporary folder, no previous bundle.
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["mbs-tool", "other", "users-folder", "users-file", "users-link", "bundle", "bundle-link"]
    )


def test_prepare_leaves_a_users_partial_folder_alone(tmp_path: Path) -> None:
    binary = small_binary(tmp_path / "mbs-tool")
    users = tmp_path / "bundle.partial"
    users.mkdir()
    (users / "keep.txt").write_text("mine\n")
    done = prepare(str(tmp_path / "bundle"), "--binary", str(binary), "--no-autotune")
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "bundle" / "mbs-tool.xz").is_file()
    assert [p.name for p in users.iterdir()] == ["keep.txt"] and (users / "keep.txt").read_text() == "mine\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bundle", "bundle.partial", "mbs-tool"]


def test_prepare_takes_out_with_a_trailing_slash_as_out(tmp_path: Path) -> None:
    binary = small_binary(tmp_path / "mbs-tool")
    bundle = tmp_path / "bundle"
    done = prepare(f"{bundle}/", "--binary", str(binary), "--no-autotune")
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"{bundle} is " in done.stdout
    assert lzma.decompress((bundle / "mbs-tool.xz").read_bytes()) == binary.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bundle", "mbs-tool"]
    done = prepare(f"{bundle}//", "--binary", str(binary), "--no-autotune")
    assert done.returncode == 2 and f"{bundle} already exists" in done.stderr, done.stderr
    assert (bundle / "mbs-tool.xz").is_file()


def test_prepare_takes_relative_paths_from_the_callers_folder(tmp_path: Path) -> None:
    small_binary(tmp_path / "mbs-tool")
    name = f"gpu-bundle-{tmp_path.name}"
    assert not (ROOT / name).exists()
    done = prepare(name, "--binary", "mbs-tool", "--no-autotune", cwd=tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    assert not (ROOT / name).exists()
    assert lzma.decompress((tmp_path / name / "mbs-tool.xz").read_bytes()) == (tmp_path / "mbs-tool").read_bytes()
    # The repository's own folders are never OUT by accident: `crates` from
    # here is tmp_path/crates, and an existing one is refused.
    (tmp_path / "crates").mkdir()
    done = prepare("crates", "--force", "--binary", "mbs-tool", "--no-autotune", cwd=tmp_path)
    assert done.returncode == 2 and str(tmp_path / "crates") in done.stderr, done.stderr
    assert (ROOT / "crates").is_dir()


def test_prepare_checks_every_input_before_building(tmp_path: Path) -> None:
    # A cargo that records being run: no check may come after a build.
    fake = tmp_path / "bin"
    fake.mkdir()
    ran = tmp_path / "cargo-ran"
    (fake / "cargo").write_text(f'#!/bin/sh\necho "$@" >> "{ran}"\nexit 1\n')
    (fake / "cargo").chmod(0o755)
    env = dict(os.environ, PATH=f"{fake}{os.pathsep}{os.environ['PATH']}")
    binary = small_binary(tmp_path / "mbs-tool")
    missing = tmp_path / "no-such-binary"
    (tmp_path / "raft-without-core").mkdir()
    out = tmp_path / "bundle"
    cases: list[tuple[list[str], str]] = [
        ([str(out), "--binary", str(missing)], f"--binary {missing}: no such file"),
        ([str(out), "--binary", str(binary), "--autotune-binary", str(missing)], f"{missing}: no such file"),
        ([str(out), "--binary", str(tmp_path), "--no-autotune"], "not a regular file"),
        ([str(out), "--official-raft", str(tmp_path / "raft-without-core")], "has no core/ folder"),
        ([str(out), "--official-igev", str(tmp_path / "raft-without-core")], "has no core/ folder"),
        ([str(tmp_path / "no-parent" / "bundle"), "--binary", str(binary)], "does not exist"),
        ([str(out), "--binary"], "--binary needs a value"),
        ([str(out), "--no-autotune", "--autotune-binary", str(binary)], "contradict"),
        ([str(out), "--frobnicate"], "unknown argument '--frobnicate'"),
        ([], "OUT is missing"),
    ]
    for argv, message in cases:
        start = time.monotonic()
        done = prepare(*argv, env=env)
        assert done.returncode == 2, (argv, done.stdout + done.stderr)
        assert message in done.stderr.splitlines()[0], (argv, done.stderr)
        assert time.monotonic() - start < 30, argv
        assert not ran.exists(), (argv, ran.read_text())
        assert not out.exists() and not (tmp_path / "no-parent").exists(), argv
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bin", "mbs-tool", "raft-without-core"]


# run.py unpacks its binaries atomically: a temporary name beside the
# binary, renamed when the archive has been read to its end.

FAKE_TOOL = b'#!/bin/sh\necho "$0 $*" >> "$(dirname "$0")/calls.log"\nexit 3\n'


def bundle_with(tmp_path: Path, archive: bytes) -> Path:
    folder = tmp_path / "bundle"
    folder.mkdir()
    shutil.copy(ROOT / "tools" / "gpu" / "run.py", folder / "run.py")
    (folder / "mbs-tool.xz").write_bytes(archive)
    return folder


def run_bundle(folder: Path, out: Path) -> subprocess.CompletedProcess[str]:
    # The probe is the first phase that runs the binary: the fake one fails
    # it at once, which ends the run.
    return subprocess.run(
        [sys.executable, str(folder / "run.py"), "--device", "cpu", "--small", "--phases", "probe", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )


def corrupt(data: bytes) -> bytes:
    middle = len(data) // 2
    return data[:middle] + bytes([data[middle] ^ 0xFF]) + data[middle + 1 :]


@pytest.mark.parametrize(
    "kind, archive",
    [
        ("truncated", lzma.compress(FAKE_TOOL * 100)[:-20]),
        ("corrupt", corrupt(lzma.compress(FAKE_TOOL * 100))),
        ("corrupt", b"not an xz archive at all\n" * 10),
        ("empty", lzma.compress(b"")),
    ],
    ids=["truncated", "corrupt", "not-xz", "empty"],
)
def test_run_refuses_a_broken_archive_in_one_line_and_leaves_nothing(tmp_path: Path, kind: str, archive: bytes) -> None:
    folder = bundle_with(tmp_path, archive)
    done = run_bundle(folder, tmp_path / "results")
    assert done.returncode != 0, done.stdout + done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    line = one_line(done.stderr)
    assert line.startswith(f"run.py: {folder / 'mbs-tool.xz'}: ") and kind in line, line
    assert sorted(p.name for p in folder.iterdir()) == ["mbs-tool.xz", "run.py"]
    assert not (tmp_path / "results").exists()


def test_run_unpacks_afresh_over_an_interrupted_unpack(tmp_path: Path) -> None:
    folder = bundle_with(tmp_path, lzma.compress(FAKE_TOOL))
    # What an interrupted unpack leaves: a temporary file of this run.py,
    # and a binary cut short by an older one's unpack in place.
    leftover = folder / ".mbs-tool.interrupted.unpacking"
    leftover.write_bytes(FAKE_TOOL[:12])
    (folder / "mbs-tool").write_bytes(FAKE_TOOL[:10])
    done = run_bundle(folder, tmp_path / "results")
    assert done.returncode == 1, done.stdout + done.stderr
    assert "synth-small: exit 3" in done.stdout, done.stdout
    assert (folder / "mbs-tool").read_bytes() == FAKE_TOOL
    assert os.access(folder / "mbs-tool", os.X_OK)
    assert (folder / "calls.log").read_text().startswith(f"{folder / 'mbs-tool'} synth ")
    assert leftover.read_bytes() == FAKE_TOOL[:12]
    # A complete unpack is reused as it is; a new archive is unpacked again.
    unpacked = (folder / "mbs-tool").stat().st_mtime_ns
    assert run_bundle(folder, tmp_path / "results").returncode == 1
    assert (folder / "mbs-tool").stat().st_mtime_ns == unpacked
    newer = FAKE_TOOL.replace(b"exit 3", b"exit 4")
    (folder / "mbs-tool.xz").write_bytes(lzma.compress(newer))
    done = run_bundle(folder, tmp_path / "results")
    assert "synth-small: exit 4" in done.stdout, done.stdout + done.stderr
    assert (folder / "mbs-tool").read_bytes() == newer
    assert {p.name for p in folder.iterdir()} == {
        "run.py",
        "mbs-tool.xz",
        "mbs-tool",
        ".mbs-tool.unpacked",
        "calls.log",
        leftover.name,
    }


def test_run_leaves_a_binary_it_did_not_unpack_alone(tmp_path: Path) -> None:
    folder = bundle_with(tmp_path, lzma.compress(FAKE_TOOL))
    users = b"#!/bin/sh\necho a binary of the user's own\n"
    (folder / "mbs-tool").write_bytes(users)
    done = run_bundle(folder, tmp_path / "results")
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stdout + done.stderr
    line = one_line(done.stderr)
    assert f"{folder / 'mbs-tool'} is not mbs-tool.xz's content" in line and "--binary" in line, line
    assert (folder / "mbs-tool").read_bytes() == users
    assert sorted(p.name for p in folder.iterdir()) == ["mbs-tool", "mbs-tool.xz", "run.py"]
