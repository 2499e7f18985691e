"""The GPU check (tools/gpu) on the CPU, so that it cannot rot before a GPU
runs it: `run.py --device cpu --small` goes through every phase with the
mbs-tool of this tree (the official code's parts are recorded as not run:
the repository never holds that code; the same binary stands in for the
autotune build), and `prepare.sh` assembles its folder, compresses the
binaries losslessly and refuses a folder over the limit (32 MiB with one
binary, 48 MiB with the autotune build too), leaving nothing behind.
Both delete only what they made: prepare.sh refuses an existing OUT (with
--force it replaces only a bundle of its own, and refuses one that holds
results), never touches OUT.partial, takes relative paths from the
caller's folder and checks every input before building; run.py unpacks its
binaries under a temporary name and renames them when complete, and
refuses a broken archive in one line. A second run.py into the same --out
merges into its results.json and gpu_samples.csv (a stub mbs-tool stands
in: no build needed), and run.py writes nothing through a link, each file
under a fresh temporary name renamed when complete.
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


# run.py keeps results (issue 57): a second run into --out merges into its
# results.json and gpu_samples.csv, and no write follows a link.

RUN = ROOT / "tools" / "gpu" / "run.py"

# An mbs-tool that trains in no time: `train` writes a train.jsonl of its
# steps (fails when a file fail-BACKBONE lies beside it), `synth` a manifest.
STUB_TOOL = """
import json, sys
from pathlib import Path

args = sys.argv[1:]
out = Path(args[args.index("--out") + 1])
if args[0] == "train":
    backbone = args[args.index("--backbone") + 1]
    if (Path(__file__).parent / f"fail-{backbone}").exists():
        sys.exit(f"stub: {backbone} fails")
    out.mkdir(parents=True, exist_ok=True)
    steps = range(int(args[args.index("--steps") + 1]))
    lines = [{"step": s, "loss": 1 / (s + 1), "grad_norm": 2.0, "samples_per_s": 10.0 + s} for s in steps]
    (out / "train.jsonl").write_text("".join(json.dumps(line) + "\\n" for line in lines))
elif args[0] == "synth":
    out.mkdir(parents=True, exist_ok=True)
    (out / "manifest.json").write_text("{}\\n")
"""

# An nvidia-smi with one GPU, so that gpu_samples.csv is written.
FAKE_NVIDIA_SMI = """#!/bin/sh
case "$*" in
    *memory.used*) echo "1234, 56" ;;
    -L) echo "GPU 0: stub" ;;
    *) echo "999.9" ;;
esac
"""


def stub_tools(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    """The stub mbs-tool, and an environment with the fake nvidia-smi."""
    folder = tmp_path / "tools"
    folder.mkdir()
    tool = folder / "mbs-tool"
    tool.write_text(f"#!{sys.executable}\n{STUB_TOOL}")
    (folder / "nvidia-smi").write_text(FAKE_NVIDIA_SMI)
    for script in folder.iterdir():
        script.chmod(0o755)
    return tool, dict(os.environ, PATH=f"{folder}{os.pathsep}{os.environ['PATH']}")


def run_check(
    tool: Path, env: dict[str, str], out: Path, phases: str, device: str = "cpu"
) -> subprocess.CompletedProcess[str]:
    argv = [sys.executable, str(RUN), "--device", device, "--small", "--binary", str(tool), "--out", str(out)]
    return subprocess.run([*argv, "--phases", phases], capture_output=True, text=True, timeout=300, env=env)


def entry_text(results: str, name: str) -> str:
    """The lines of a phase's entry in results.json, as written."""
    lines = results.splitlines()
    start = lines.index(f'    "{name}": {{')
    end = next(i for i in range(start, len(lines)) if lines[i] in ("    }", "    },"))
    return "\n".join(lines[start:end] + ["    }"])


def snapshot(folder: Path) -> dict[str, object]:
    """Every path under `folder`: a file's bytes, a link's target, or None
    for a folder."""
    found: dict[str, object] = {}
    for path in sorted(folder.rglob("*")):
        name = str(path.relative_to(folder))
        found[name] = os.readlink(path) if path.is_symlink() else path.read_bytes() if path.is_file() else None
    return found


def test_a_second_run_keeps_the_first_runs_phases(tmp_path: Path) -> None:
    tool, env = stub_tools(tmp_path)
    out = tmp_path / "results"
    (tool.parent / "fail-raft-stereo").write_text("")
    first = run_check(tool, env, out, "compact,raft-stereo")
    assert first.returncode == 1 and "stub: raft-stereo fails" in first.stdout, first.stdout + first.stderr
    before = (out / "results.json").read_text()
    samples = (out / "gpu_samples.csv").read_text()
    log = (out / "logs" / "compact-device.log").read_bytes()
    assert json.loads(before)["phases"]["raft-stereo"]["status"] == "failed"
    assert samples.startswith("time_s,memory_used_mib,utilization_percent\n") and ",1234,56\n" in samples

    (tool.parent / "fail-raft-stereo").unlink()
    second = run_check(tool, env, out, "raft-stereo")
    assert second.returncode == 0, second.stdout + second.stderr
    after = (out / "results.json").read_text()
    results = json.loads(after)
    assert list(results["phases"]) == ["environment", "probe", "compact", "raft-stereo"]
    assert entry_text(after, "compact") == entry_text(before, "compact")
    assert results["phases"]["compact"]["run"] == 1 and "finished" in results["phases"]["compact"]
    for name in ["environment", "probe", "raft-stereo"]:
        assert results["phases"][name]["run"] == 2 and results["phases"][name]["status"] == "ok", name
    assert [(run["run"], run["phases"]) for run in results["runs"]] == [
        (1, ["environment", "probe", "compact", "raft-stereo"]),
        (2, ["environment", "probe", "raft-stereo"]),
    ]
    assert all(run["started"] and run["binary"] == str(tool) for run in results["runs"])
    assert (out / "logs" / "compact-device.log").read_bytes() == log
    newer = (out / "gpu_samples.csv").read_text()
    assert newer.startswith(samples) and len(newer.splitlines()) > len(samples.splitlines())
    assert newer.count("time_s") == 1
    assert "(run 1) loss within" in second.stdout, second.stdout
    assert not [p.name for p in out.rglob("*.partial")]


@pytest.mark.parametrize(
    "results, device, message",
    [
        (None, "vulkan", "holds a run with --device cpu --small"),
        ('{"mine": true}\n', "cpu", "is not a results.json of run.py"),
        ("not json\n", "cpu", "is not a results.json of run.py"),
    ],
    ids=["other-device", "other-json", "not-json"],
)
def test_run_refuses_results_it_cannot_merge_with_and_changes_nothing(
    tmp_path: Path, results: str | None, device: str, message: str
) -> None:
    tool, env = stub_tools(tmp_path)
    out = tmp_path / "results"
    assert run_check(tool, env, out, "probe").returncode == 0
    if results is not None:
        (out / "results.json").write_text(results)
    before = snapshot(out)
    done = run_check(tool, env, out, "probe", device=device)
    assert done.returncode == 2, done.stdout + done.stderr
    line = one_line(done.stderr)
    assert line.startswith(f"run.py: {out / 'results.json'} ") and message in line, line
    assert snapshot(out) == before


def test_run_merges_into_a_results_json_of_an_older_run_py(tmp_path: Path) -> None:
    tool, env = stub_tools(tmp_path)
    out = tmp_path / "results"
    out.mkdir()
    figures = {"loss_relative_error": 0.0, "grad_norm_relative_error": 0.0}
    compact = {"status": "ok", "figures": figures, "seconds": 1.0}
    older = {"device": "cpu", "small": True, "binary": "/old/mbs-tool", "autotune_binary": None, "phases": {}}
    older["phases"] = {"compact": compact}
    (out / "results.json").write_text(json.dumps(older, indent=2) + "\n")
    done = run_check(tool, env, out, "probe")
    assert done.returncode == 0, done.stdout + done.stderr
    results = json.loads((out / "results.json").read_text())
    assert results["phases"]["compact"] == compact
    assert [(run["run"], run["binary"], run["phases"]) for run in results["runs"]] == [
        (1, "/old/mbs-tool", ["compact"]),
        (2, str(tool), ["environment", "probe"]),
    ]


@pytest.mark.parametrize("name", ["results.json", "gpu_samples.csv", "logs", "logs/probe.log", "lib"])
def test_run_refuses_a_link_in_out_before_writing_anything(tmp_path: Path, name: str) -> None:
    tool, env = stub_tools(tmp_path)
    out = tmp_path / "results"
    assert run_check(tool, env, out, "probe").returncode == 0
    elsewhere = tmp_path / "elsewhere"
    if name in ("logs", "lib"):
        elsewhere.mkdir()
        (elsewhere / "probe.log").write_text("mine\n")
    else:
        elsewhere.write_text("mine\n")
    path = out / name
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()
    path.symlink_to(elsewhere)
    before, theirs = snapshot(out), snapshot(tmp_path / "tools")
    done = run_check(tool, env, out, "probe")
    assert done.returncode == 2, done.stdout + done.stderr
    expected = f"run.py: {path} is a symbolic link: run.py writes nothing through a link"
    assert one_line(done.stderr) == f"{expected}; move it away, or choose another --out"
    assert snapshot(out) == before and snapshot(tmp_path / "tools") == theirs
    if elsewhere.is_dir():
        assert [p.name for p in elsewhere.iterdir()] == ["probe.log"]
        assert (elsewhere / "probe.log").read_text() == "mine\n"
    else:
        assert elsewhere.read_text() == "mine\n"


def test_run_writes_under_a_fresh_temporary_name_not_through_a_link(tmp_path: Path) -> None:
    tool, env = stub_tools(tmp_path)
    out = tmp_path / "results"
    out.mkdir()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.write_text("mine\n")
    # The name an older run.py wrote results.json under before renaming it.
    (out / "results.json.partial").symlink_to(elsewhere)
    done = run_check(tool, env, out, "probe")
    assert done.returncode == 0, done.stdout + done.stderr
    assert elsewhere.read_text() == "mine\n"
    assert os.readlink(out / "results.json.partial") == str(elsewhere)
    assert json.loads((out / "results.json").read_text())["phases"]["probe"]["status"] == "ok"
    assert not (out / "results.json").is_symlink()
    # lib/ (a libnccl.so link) is made only where the Python environment has
    # NCCL, as PyTorch's CUDA wheels bring it: the test environment's does.
    assert sorted(p.name for p in out.iterdir() if p.name != "lib") == [
        "data",
        "gpu_samples.csv",
        "logs",
        "results.json",
        "results.json.partial",
        "runs",
    ]


def test_run_refuses_a_link_at_the_unpack_stamp_and_unpacks_nothing(tmp_path: Path) -> None:
    folder = bundle_with(tmp_path, lzma.compress(FAKE_TOOL))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.write_text("mine\n")
    (folder / ".mbs-tool.unpacked").symlink_to(elsewhere)
    done = run_bundle(folder, tmp_path / "results")
    assert done.returncode == 2, done.stdout + done.stderr
    line = one_line(done.stderr)
    assert line.startswith(f"run.py: {folder / '.mbs-tool.unpacked'} is a symbolic link") and "--binary" in line
    assert elsewhere.read_text() == "mine\n" and os.readlink(folder / ".mbs-tool.unpacked") == str(elsewhere)
    assert sorted(p.name for p in folder.iterdir()) == [".mbs-tool.unpacked", "mbs-tool.xz", "run.py"]
    assert not (tmp_path / "results").exists()


# prepare.sh --force never deletes results (issue 57): a bundle holding
# anything but what prepare.sh and run.py's unpack put there is refused.

RUN_PY_MADE = ["mbs-tool", ".mbs-tool.unpacked", "bench/__pycache__/s3_torch.cpython-311.pyc"]


def made_bundle(tmp_path: Path) -> tuple[Path, Path]:
    """A bundle of prepare.sh's with what run.py makes beside itself."""
    binary = small_binary(tmp_path / "mbs-tool")
    bundle = tmp_path / "bundle"
    assert prepare(str(bundle), "--binary", str(binary), "--no-autotune").returncode == 0
    for name in RUN_PY_MADE:
        (bundle / name).parent.mkdir(exist_ok=True)
        (bundle / name).write_bytes(b"made by run.py\n")
    return bundle, small_binary(tmp_path / "other", seed=7)


def users_files(bundle: Path, names: list[str]) -> list[Path]:
    """Makes each file, with the folders it needs, in `bundle`: what was
    made, in order."""
    made: list[Path] = []
    for name in names:
        path = bundle / name
        for folder in reversed(path.parents):
            if bundle in folder.parents and not folder.exists():
                folder.mkdir()
                made.append(folder)
        path.write_text(f"the user's {name}\n")
        made.append(path)
    return made


@pytest.mark.parametrize(
    "results, named",
    [
        (["results/results.json", "results/logs/probe.log", "results/gpu_samples.csv"], "results/results.json"),
        (["results/logs/probe.log"], "results"),
        (["data/mine/results.json"], "data/mine/results.json"),
        (["official/gpu_samples.csv"], "official/gpu_samples.csv"),
        (["notes.txt"], "notes.txt"),
    ],
    ids=["results", "results-without-json", "results-json-deeper", "samples-deeper", "users-file"],
)
def test_prepare_force_refuses_a_bundle_holding_results_and_changes_nothing(
    tmp_path: Path, results: list[str], named: str
) -> None:
    bundle, other = made_bundle(tmp_path)
    made = users_files(bundle, results)
    before = snapshot(tmp_path)
    done = prepare(str(bundle), "--force", "--binary", str(other), "--no-autotune")
    assert done.returncode == 2, done.stdout + done.stderr
    line = one_line(done.stderr)
    assert line.startswith(f"prepare.sh: {bundle} holds results or files prepare.sh did not put there ("), line
    assert named in line and "--force never deletes them" in line, line
    assert snapshot(tmp_path) == before
    # Without them, the bundle and what run.py made in it are replaced.
    for path in reversed(made):
        if path.is_dir():
            path.rmdir()
        else:
            path.unlink()
    done = prepare(str(bundle), "--force", "--binary", str(other), "--no-autotune")
    assert done.returncode == 0, done.stdout + done.stderr
    assert lzma.decompress((bundle / "mbs-tool.xz").read_bytes()) == other.read_bytes()
    assert not (bundle / "mbs-tool").exists() and not (bundle / "bench" / "__pycache__").exists()


def assert_refused_with_late_results(
    done: subprocess.CompletedProcess[str], bundle: Path, before: dict[str, object], tmp_path: Path
) -> None:
    """`prepare.sh --force` refused (exit 2, naming the results that
    appeared in the bundle while it ran) and left the bundle as it was
    with those results, and nothing else beside it."""
    assert done.returncode == 2, done.stdout + done.stderr
    line = done.stderr.strip().splitlines()[-1]
    assert line.startswith(f"prepare.sh: {bundle} holds results") and "results/results.json" in line, line
    assert snapshot(bundle) == {**before, "results": None, "results/results.json": b"{}\n"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bin", "bundle", "mbs-tool", "other"]


def test_prepare_force_refuses_results_made_during_the_build(tmp_path: Path) -> None:
    bundle, other = made_bundle(tmp_path)
    # An xz that starts a run in the bundle while the new one is compressed.
    fake = tmp_path / "bin"
    fake.mkdir()
    xz = shutil.which("xz")
    assert xz is not None
    results = bundle / "results"
    (fake / "xz").write_text(
        f'#!/bin/sh\nmkdir -p "{results}"\necho "{{}}" > "{results}/results.json"\nexec {xz} "$@"\n'
    )
    (fake / "xz").chmod(0o755)
    env = dict(os.environ, PATH=f"{fake}{os.pathsep}{os.environ['PATH']}")
    before = snapshot(bundle)
    done = prepare(str(bundle), "--force", "--binary", str(other), "--no-autotune", env=env)
    assert_refused_with_late_results(done, bundle, before, tmp_path)


def test_prepare_force_puts_back_a_bundle_given_results_as_it_is_moved(tmp_path: Path) -> None:
    bundle, other = made_bundle(tmp_path)
    # An mv that lets a run write results.json just before the bundle moves.
    fake = tmp_path / "bin"
    fake.mkdir()
    mv = shutil.which("mv")
    results = bundle / "results"
    (fake / "mv").write_text(
        f'#!/bin/sh\nif [ "$2" = "{bundle}" ]; then mkdir "{results}" && echo "{{}}" > "{results}/results.json"; fi\n'
        f'exec {mv} "$@"\n'
    )
    (fake / "mv").chmod(0o755)
    env = dict(os.environ, PATH=f"{fake}{os.pathsep}{os.environ['PATH']}")
    before = snapshot(bundle)
    done = prepare(str(bundle), "--force", "--binary", str(other), "--no-autotune", env=env)
    assert_refused_with_late_results(done, bundle, before, tmp_path)


def test_an_unknown_phase_is_refused_before_anything_is_written(tmp_path: Path) -> None:
    tool, env = stub_tools(tmp_path)
    out = tmp_path / "results"
    done = run_check(tool, env, out, "probe,igevv")
    assert done.returncode == 2, done.stderr
    assert "no phase named igevv" in done.stderr
    assert not out.exists()
