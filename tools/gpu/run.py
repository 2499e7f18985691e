#!/usr/bin/env python3
"""The GPU check: one command that answers whether mbs trains and predicts
on CUDA, correctly, and how fast against the official PyTorch code on the
same GPU. Run it from the folder `tools/gpu/prepare.sh` made, on the GPU
machine (no network, no Rust):

    python3 run.py --out results            # --device cuda by default

Phases, in order of value, each under its own timeout; a phase that fails
is recorded and the next one runs, except the probe, whose failure ends
the run with a diagnosis:

1. environment: nvidia-smi, where libcuda, NVRTC and the CUDA headers are,
   and the environment set for the rest (LD_LIBRARY_PATH, CUDA_PATH);
2. probe: one training step of the compact network on the device;
3. compact: 4 S3 steps on the device against the same steps on the CPU
   (loss and gradient norm within a tolerance that allows for TF32);
4. raft-stereo, igev: the S3 step at the paper's size (384x512, official
   iteration counts) with its time and peak GPU memory, next to the
   official PyTorch code's same step on the same device;
5. precision: the RAFT-Stereo step in bf16 and f16, mbs and PyTorch;
6. predict: RAFT-Stereo weights in the official layout (`mbs-tool export`
   of phase 4's run) predicted by mbs on the device, by mbs on the CPU and
   by the official model on the device;
7. autotune: phase 4's steps again with the binary built with burn's
   autotune (`mbs-tool-autotune.xz`, or --autotune-binary), its time over
   the default build's: the figure that decides whether mbs's CUDA build
   turns autotune on (docs/gpus.md, "Kernels").

Everything goes to --out as it happens: results.json (rewritten after each
phase), logs/ (each command's output), gpu_samples.csv (nvidia-smi every
half second); a short table is printed last.

A second run into the same --out (say `--phases igev` after a failure)
merges into its results: the phases run now (environment and probe always
run) replace those phases' entries, every other entry is kept as it was,
and gpu_samples.csv keeps the earlier rows. results.json lists the runs
("runs": number, start, binaries, phases run) and each phase entry names
its run and when it finished ("run", "finished"). A results.json of
another --device or --small, or not run.py's, is refused (exit 2): choose
another --out. run.py writes no file through a symbolic link: a link at
results.json, gpu_samples.csv, logs/, lib/ or a log is refused (exit 2, a
line naming it) before anything is written, and every file it writes is
made under a temporary name beside it and renamed when complete. What the
mbs-tool commands write (data/, runs/, predict/) follows their own rules.

`--device cpu --small` runs
every phase on the CPU at small sizes (CI runs it so that it cannot rot);
the official code's parts need `official/RAFT-Stereo` and
`official/IGEV-Stereo` beside this script (prepare.sh puts them there) and
PyTorch, and are recorded as not run without them.
"""

import argparse
import glob
import json
import lzma
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

# The permissions a file gets from open() (mkstemp makes 0600), read while
# the process has one thread.
UMASK = os.umask(0)
os.umask(UMASK)

HERE = Path(__file__).resolve().parent
# In the prepared folder the benchmarks and the test pair lie beside this
# script; in the repository, in tools/bench and testdata.
BENCH = HERE / "bench" if (HERE / "bench").is_dir() else HERE.parent / "bench"
PAIR = HERE / "data" / "pair" if (HERE / "data" / "pair").is_dir() else HERE.parent.parent / "testdata" / "middlebury-baby2"


class PhaseError(Exception):
    """A phase's failure, with what it found."""


class Refused(Exception):
    """A path in --out that run.py will not write: a link, or not what it
    writes there."""


def writable(path, kind="file", other="choose another --out"):
    """Refused when `path` is a symbolic link, or is there and is not a
    `kind` ("file": a regular file, or "folder"); the message ends with the
    `other` way out."""
    if path.is_symlink():
        raise Refused(f"{path} is a symbolic link: run.py writes nothing through a link; move it away, or {other}")
    if path.exists() and not (path.is_dir() if kind == "folder" else path.is_file()):
        raise Refused(f"{path} is in the way: run.py writes a {kind} there; move it away, or {other}")


def make_folder(path):
    """`path` as a folder (made when absent); Refused when it is a link or
    not a folder."""
    try:
        path.mkdir()
    except FileExistsError:
        writable(path, "folder")


def write_file(path, text):
    """Writes `text` to `path` under a temporary name beside it (made anew,
    so never through a link) and renames it over `path` when complete:
    Refused when `path` is a link or not a file; the temporary file is
    removed on failure."""
    writable(path)
    descriptor, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".partial")
    try:
        os.fchmod(descriptor, 0o666 & ~UMASK)
        with os.fdopen(descriptor, "w") as target:
            target.write(text)
        os.replace(temporary, path)
    finally:
        if os.path.lexists(temporary):
            os.unlink(temporary)


def check_output(args):
    """Every check of --out, before anything is written: the folders and
    files run.py writes there are absent or real folders and files (no
    links), and a results.json there is one a run of this --device and
    --small size can merge into. Its results ({} when none) and samples."""
    out = args.out.resolve()
    writable(out, "folder")
    for path, kind in [(out / "logs", "folder"), (out / "lib", "folder"), (out / "gpu_samples.csv", "file")]:
        writable(path, kind)
    if (out / "logs").is_dir():
        for log in sorted((out / "logs").glob("*.log")):
            writable(log)
    refuse_foreign_nccl_link(out / "lib" / "libnccl.so")
    samples = out / "gpu_samples.csv"
    return previous_results(out / "results.json", args), samples.read_text() if samples.exists() else ""


def previous_results(path, args):
    """The results at `path` that this run merges into ({} when none);
    Refused when they are not run.py's, or of another --device or size."""
    writable(path)
    if not path.exists():
        return {}
    try:
        results = json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise Refused(f"{path} is not a results.json of run.py ({error}): move it away, or choose another "
                      "--out") from None
    if not isinstance(results, dict) or not isinstance(results.get("phases"), dict):
        raise Refused(f"{path} is not a results.json of run.py (no phases): move it away, or choose another --out")
    if [results.get("device"), results.get("small")] != [args.device, args.small]:
        raise Refused(f"{path} holds a run with --device {results.get('device')}"
                      f"{' --small' if results.get('small') else ''}, which this run's results would be mixed "
                      "with: choose another --out")
    return results


def refuse_foreign_nccl_link(path):
    """Refused when something is at `path` other than a link to a
    libnccl.so.2, which environment() makes there."""
    ours = path.is_symlink() and Path(os.readlink(path)).name == "libnccl.so.2"
    if (path.exists() or path.is_symlink()) and not ours:
        raise Refused(f"{path} is not the link to libnccl.so.2 run.py makes: move it away, or choose another --out")


def now():
    """The local time, to the second, with its offset from UTC."""
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


class Check:
    """The run: its settings, environment, output folder and results (the
    previous run's in --out, merged)."""

    def __init__(self, args, previous):
        self.args = args
        self.out = args.out.resolve()
        self.logs = self.out / "logs"
        self.out.parent.mkdir(parents=True, exist_ok=True)
        make_folder(self.out)
        make_folder(self.logs)
        self.env = dict(os.environ)
        runs = earlier_runs(previous)
        self.run = {"run": len(runs) + 1, "started": now(), "binary": str(args.binary),
                    "autotune_binary": args.autotune_binary and str(args.autotune_binary), "phases": []}
        self.results = {"device": args.device, "small": args.small, "runs": runs + [self.run],
                        "phases": dict(previous.get("phases", {}))}
        self.sampler = None

    def record(self, name, record):
        """Records a phase of this run (replacing an earlier run's entry for
        it) and saves the results."""
        record.update(run=self.run["run"], finished=now())
        self.results["phases"][name] = record
        self.run["phases"].append(name)
        self.save()

    def save(self):
        """results.json, with the phases in their running order."""
        phases = self.results["phases"]
        known = [name for name, _, _ in PHASES]
        order = sorted(phases, key=lambda name: known.index(name) if name in known else len(known))
        self.results["phases"] = {name: phases[name] for name in order}
        write_file(self.out / "results.json", json.dumps(self.results, indent=2) + "\n")

    def command(self, name, argv, timeout, env=None):
        """Runs argv with its output in logs/NAME.log; its stdout, or a
        PhaseError with the log's tail."""
        log = self.logs / f"{name}.log"
        start = time.time()
        try:
            done = subprocess.run([str(a) for a in argv], capture_output=True, text=True, timeout=timeout,
                                  env=env or self.env)
        except subprocess.TimeoutExpired as error:
            write_file(log, f"$ {' '.join(map(str, argv))}\n(timed out after {timeout} s)\n"
                       f"{text(error.stdout)}{text(error.stderr)}")
            raise PhaseError(f"{name}: timed out after {timeout} s (logs/{name}.log)") from None
        write_file(log, f"$ {' '.join(map(str, argv))}\n({time.time() - start:.1f} s, exit {done.returncode})\n"
                   f"--- stdout\n{done.stdout}\n--- stderr\n{done.stderr}")
        if done.returncode != 0:
            tail = "\n".join((done.stdout + done.stderr).strip().splitlines()[-6:])
            raise PhaseError(f"{name}: exit {done.returncode} (logs/{name}.log):\n{tail}")
        return done.stdout

    def mbs(self, name, *argv, timeout, binary=None):
        return self.command(name, [binary or self.args.binary, *argv], timeout)

    def peak_gpu_mib(self, since):
        """The most GPU memory nvidia-smi saw in use since `since` (MiB)."""
        return self.sampler.peak_since(since) if self.sampler else None


def text(output):
    """A timed-out command's output so far: TimeoutExpired gives bytes
    even when the command ran with text=True."""
    if isinstance(output, bytes):
        return output.decode(errors="replace")
    return output or ""


def earlier_runs(previous):
    """The runs recorded in a previous results.json; one written before
    run.py recorded its runs counts as run 1, with the phases it holds."""
    if "runs" in previous or not previous.get("phases"):
        return list(previous.get("runs", []))
    return [{"run": 1, "started": None, "binary": previous.get("binary"),
             "autotune_binary": previous.get("autotune_binary"), "phases": list(previous["phases"])}]


class GpuSampler(threading.Thread):
    """nvidia-smi's memory and utilisation every half second, into
    gpu_samples.csv after the earlier runs' rows (the file is written anew
    every ten seconds and at the end) and into memory for the phases'
    peaks."""

    HEADER = "time_s,memory_used_mib,utilization_percent\n"

    def __init__(self, path, earlier):
        super().__init__(daemon=True)
        self.path, self.samples, self.stop, self.error = path, [], threading.Event(), None
        self.rows = [earlier + ("" if earlier.endswith("\n") else "\n") if earlier else self.HEADER]

    def run(self):
        try:
            while not self.stop.is_set() and self.sample():
                if len(self.samples) % 20 == 0:
                    self.write()
                self.stop.wait(0.5)
            self.write()
        except (OSError, Refused) as error:
            self.error = str(error)

    def sample(self):
        """One reading of nvidia-smi's; False when it gives none."""
        query = ["nvidia-smi", "--query-gpu=memory.used,utilization.gpu", "--format=csv,noheader,nounits"]
        try:
            line = subprocess.run(query, capture_output=True, text=True, timeout=5).stdout.splitlines()[0]
            memory, utilisation = (float(v) for v in line.split(","))
        except (OSError, IndexError, ValueError, subprocess.TimeoutExpired):
            return False
        when = time.time()
        self.samples.append((when, memory))
        self.rows.append(f"{when:.2f},{memory:.0f},{utilisation:.0f}\n")
        return True

    def write(self):
        write_file(self.path, "".join(self.rows))

    def finish(self):
        """Stops the sampling; the last write's error, if any."""
        self.stop.set()
        self.join()
        return self.error

    def peak_since(self, since):
        used = [memory for when, memory in self.samples if when >= since]
        return max(used) if used else None


def read_pfm(path):
    """A single-channel PFM as a list of rows (no NumPy needed)."""
    import struct

    with open(path, "rb") as f:
        kind = f.readline().strip()
        width, height = (int(v) for v in f.readline().split())
        scale = float(f.readline())
        if kind != b"Pf":
            raise PhaseError(f"{path}: not a single-channel PFM")
        data = f.read()
    endian = "<" if scale < 0 else ">"
    values = struct.unpack(f"{endian}{width * height}f", data[: 4 * width * height])
    rows = [list(values[r * width : (r + 1) * width]) for r in range(height)]
    return rows[::-1]  # PFM stores the bottom row first


def mean_abs_difference(a, b):
    pairs = [(x, y) for ra, rb in zip(a, b) for x, y in zip(ra, rb) if x == x and y == y and abs(x) < 1e30
             and abs(y) < 1e30]
    return sum(abs(x - y) for x, y in pairs) / max(len(pairs), 1)


def train_log(run):
    return [json.loads(line) for line in (run / "train.jsonl").read_text().splitlines() if line.strip()]


# --------------------------------------------------------------------------
# Phases


def environment(check):
    """What the machine has, and the environment the rest runs in."""
    found = {"nvidia_smi": shutil.which("nvidia-smi")}
    if found["nvidia_smi"]:
        found["gpus"] = subprocess.run(["nvidia-smi", "-L"], capture_output=True, text=True).stdout.strip()
        found["driver"] = subprocess.run(["nvidia-smi", "--query-gpu=driver_version", "--format=csv,noheader"],
                                         capture_output=True, text=True).stdout.strip()
    ldconfig = subprocess.run(["ldconfig", "-p"], capture_output=True, text=True).stdout if shutil.which(
        "ldconfig") else ""
    found["libcuda"] = [line.split("=>")[-1].strip() for line in ldconfig.splitlines() if "libcuda.so.1" in line]
    # pip's CUDA wheels (nvidia-cuda-nvrtc, nvidia-cuda-runtime, nvidia-nccl)
    # lay out site-packages/nvidia/<part or cu13>/{lib,include}.
    roots = sorted({p for p in sys.path if p and Path(p, "nvidia").is_dir()})
    libs = sorted({str(Path(p).parent) for root in roots for p in glob.glob(f"{root}/nvidia/*/lib/libnvrtc.so*")})
    includes = sorted({str(Path(p).parent) for root in roots
                       for p in glob.glob(f"{root}/nvidia/*/include/cuda_runtime.h")})
    found["nvrtc_folders"] = libs
    found["header_folders"] = includes
    # cubecl opens NCCL only as libnccl.so, which pip's nvidia-nccl wheel
    # does not have (libnccl.so.2): a link makes it visible. mbs itself sums
    # gradients through the host, so this matters only to cubecl.
    nccl = sorted(glob.glob(f"{roots[0]}/nvidia/nccl/lib/libnccl.so.2")) if roots else []
    if nccl:
        link = nccl_link(check.out / "lib", nccl[0])
        libs.append(str(link.parent))
        found["nccl_link"] = f"{link} -> {nccl[0]}"
    if libs:
        check.env["LD_LIBRARY_PATH"] = ":".join(libs + [check.env.get("LD_LIBRARY_PATH", "")]).rstrip(":")
    if "CUDA_PATH" not in check.env:
        for candidate in ["/usr/local/cuda"] + [str(Path(i).parent) for i in includes]:
            if Path(candidate, "include", "cuda_runtime.h").is_file():
                check.env["CUDA_PATH"] = candidate
                break
    found["set"] = {k: check.env[k] for k in ("LD_LIBRARY_PATH", "CUDA_PATH") if k in check.env}
    try:
        import torch

        found["torch"] = torch.__version__
        found["torch_cuda"] = torch.cuda.is_available()
    except ImportError:
        found["torch"] = None
    found["official_code"] = {name: (HERE / "official" / name).is_dir() for name in ("RAFT-Stereo", "IGEV-Stereo")}
    return found


def nccl_link(folder, target):
    """FOLDER/libnccl.so, a link to `target`: made under a temporary name
    and renamed over an earlier run's link (never followed); Refused when
    something else is there."""
    make_folder(folder)
    link = folder / "libnccl.so"
    if link.is_symlink() and os.readlink(link) == target:
        return link
    refuse_foreign_nccl_link(link)
    temporary = folder / f".libnccl.so.{os.getpid()}.{time.monotonic_ns()}.partial"
    temporary.symlink_to(target)
    try:
        os.replace(temporary, link)
    finally:
        if temporary.is_symlink():
            temporary.unlink()
    return link


def synth(check, name, width, height, frames):
    folder = check.out / "data" / name
    if not (folder / "manifest.json").is_file():
        check.mbs(f"synth-{name}", "synth", "--out", folder, "--frames", frames, "--towns", "Town01,Town10",
                  "--weathers", "ClearNoon", "--width", width, "--height", height, "--focal", width // 2,
                  "--no-checksums", timeout=300)
    return folder / "manifest.json"


def train(check, name, device, backbone, steps, crop, extra=(), timeout=300, binary=None):
    """`mbs-tool train` (the default binary unless `binary`) for `steps`
    steps with a log line per step; its folder and log."""
    run = check.out / "runs" / name
    small = check.args.small
    manifest = synth(check, "small" if small else "paper", 160 if small else 512, 96 if small else 384, 4)
    argv = ["train", manifest, "--out", run, "--device", device, "--backbone", backbone, "--steps", steps,
            "--batch-size", 2, "--crop", crop, "--seed", 5, "--val-every", 100000, "--restart",
            "--set", "log_every=1", "--set", "visual_samples=0", "--set", "checkpoint_every=100000"]
    if small:
        argv += ["--max-disparity", 32]
    if small and backbone != "compact":
        key = "raft_stereo" if backbone == "raft-stereo" else "igev"
        argv += ["--set", f"network.{key}.hidden_dim=32", "--set", f"network.{key}.gru_levels=2",
                 "--set", f"network.{key}.train_iters=2", "--set", f"network.{key}.test_iters=2"]
    start = time.time()
    check.mbs(name, *argv, *extra, timeout=timeout, binary=binary)
    return run, train_log(run), start


def steps(check):
    """Steps of a timed run: the first compiles the device's kernels, the
    rest are timed (two in all at the small sizes)."""
    return 2 if check.args.small else 4


def step_figures(log, batch):
    """Milliseconds per step over the steps after the first (which compiles
    the kernels), from train.jsonl's samples per second."""
    later = [line["samples_per_s"] for line in log[1:] if line.get("samples_per_s")]
    first = log[0].get("samples_per_s") if log else None
    return {
        "first_step_ms": round(1e3 * batch / first, 1) if first else None,
        "ms_per_step": round(1e3 * batch / (sum(later) / len(later)), 1) if later else None,
        "loss": log[-1]["loss"] if log else None,
    }


def probe(check):
    """Two steps on the device (a run has at least two): can it compile and
    launch kernels?"""
    try:
        _, log, _ = train(check, "probe", check.args.device, "compact", 2, "48x96", timeout=180)
    except PhaseError as error:
        text = str(error)
        hints = [(needle, hint) for needle, hint in [
            ("libcuda", "the driver library libcuda.so.1 is not on the loader path"),
            ("nvrtc", "NVRTC (libnvrtc.so or libnvrtc.so.13) is not on LD_LIBRARY_PATH"),
            ("cuda_runtime.h", "the CUDA headers are missing: set CUDA_PATH to a folder with include/"),
            ("feature", "the binary was built without --features cuda"),
        ] if needle in text.lower()]
        raise PhaseError(text + ("\ndiagnosis: " + "; ".join(h for _, h in hints) if hints else "")) from None
    return {"loss": log[-1]["loss"]}


def compact(check):
    """4 steps on the device against the same 4 on the CPU."""
    _, device_log, _ = train(check, "compact-device", check.args.device, "compact", 4, "48x96")
    _, cpu_log, _ = train(check, "compact-cpu", "cpu", "compact", 4, "48x96")
    rows = []
    for d, c in zip(device_log, cpu_log):
        rows.append({"step": d["step"], "loss": [d["loss"], c["loss"]], "grad_norm": [d["grad_norm"], c["grad_norm"]]})
    loss_error = max(abs(r["loss"][0] - r["loss"][1]) / max(abs(r["loss"][1]), 1e-12) for r in rows)
    grad_error = max(abs(r["grad_norm"][0] - r["grad_norm"][1]) / max(abs(r["grad_norm"][1]), 1e-12) for r in rows)
    # TF32 matmuls carry 10 mantissa bits (about 1e-3 relative a product).
    tolerance = {"loss": 1e-2, "grad_norm": 5e-2}
    result = {"steps": rows, "loss_relative_error": loss_error, "grad_norm_relative_error": grad_error,
              "tolerance": tolerance}
    if loss_error > tolerance["loss"] or grad_error > tolerance["grad_norm"]:
        raise PhaseError(f"the device departs from the CPU: {json.dumps(result)}")
    return result


def official_torch(check, network, precision="f32"):
    """The official PyTorch step (tools/bench/official_step_vs_torch.py) on
    the device, or why it did not run."""
    if precision == "f16" and check.args.device == "cpu":
        return {"not_run": "f16 on the CPU is emulated, far too slow to time"}
    folder = HERE / "official" / ("RAFT-Stereo" if network == "raft-stereo" else "IGEV-Stereo")
    if not folder.is_dir():
        return {"not_run": f"no official code at {folder}"}
    try:
        import torch  # noqa: F401
    except ImportError:
        return {"not_run": "PyTorch is not installed"}
    small = check.args.small
    argv = [sys.executable, BENCH / "official_step_vs_torch.py", "--torch-only", "--network", network,
            "--official", folder, "--device", check.args.device, "--precision", precision,
            "--steps", 1 if small else 3, "--warmup", 1, "--batch", 2, "--threads", os.cpu_count() or 1]
    if small:
        argv += ["--height", 48, "--width", 96, "--hidden-dim", 32, "--gru-levels", 2,
                 "--train-iters", 2, "--test-iters", 2]
    env = dict(check.env, PYTHONPATH=os.pathsep.join([str(HERE / "vendor"), check.env.get("PYTHONPATH", "")]))
    out = check.command(f"official-{network}-{precision}", argv, timeout=300, env=env)
    return json.loads(out.strip().splitlines()[-1])


def network_step(network):
    def phase(check):
        crop = "48x96" if check.args.small else "384x512"
        run, log, start = train(check, network, check.args.device, network, steps(check), crop, timeout=420)
        figures = {"mbs": {**step_figures(log, 2), "peak_gpu_mib": check.peak_gpu_mib(start), "crop": crop},
                   "official": official_torch(check, network)}
        ours, theirs = figures["mbs"].get("ms_per_step"), figures["official"].get("ms_per_step")
        if ours and theirs:
            figures["mbs_over_official"] = round(ours / theirs, 2)
        return figures

    return phase


def precision(check):
    crop = "48x96" if check.args.small else "384x512"
    figures = {}
    for fmt in ("bf16", "f16"):
        _, log, start = train(check, f"raft-stereo-{fmt}", check.args.device, "raft-stereo", steps(check), crop,
                              extra=("--precision", fmt), timeout=420)
        figures[fmt] = {"mbs": {**step_figures(log, 2), "peak_gpu_mib": check.peak_gpu_mib(start)},
                        "official": official_torch(check, "raft-stereo", fmt)}
    return figures


def predict(check):
    """RAFT-Stereo in the official layout, predicted three ways."""
    run = check.out / "runs" / "raft-stereo"
    if not (run / "train.jsonl").is_file():
        raise PhaseError("no raft-stereo run to export (its phase failed)")
    weights = check.out / "raft-stereo.safetensors"
    check.mbs("export", "export", run, "--out", weights, timeout=120)
    pair = [PAIR / "view1.png", PAIR / "view2.png"]
    settings = json.loads((run / "config.json").read_text())["network"]["raft_stereo"]
    sets = [a for key, value in settings.items()
            for a in ("--set", f"network.raft_stereo.{key}={json.dumps(value).strip(chr(34))}")]
    maps = {}
    for device in dict.fromkeys([check.args.device, "cpu"]):
        folder = check.out / "predict" / device.replace(":", "-")
        check.mbs(f"predict-{device}", "predict", "--left", pair[0], "--right", pair[1], "--out", folder,
                  "--backbone", "raft-stereo", "--weights", weights, *sets, "--device", device, "--overwrite",
                  timeout=300)
        maps[device] = read_pfm(next(folder.glob("*.pfm")))
    figures = {"pair": [str(p) for p in pair],
               "mbs_device_vs_cpu_mean_px": mean_abs_difference(maps[check.args.device], maps["cpu"])}
    official = HERE / "official" / "RAFT-Stereo"
    if official.is_dir():
        script = HERE / "official_predict.py"
        out = check.command("predict-official", [sys.executable, script, "--official", official, "--weights",
                                                 weights, "--config", run / "config.json", "--left", pair[0],
                                                 "--right", pair[1], "--device", check.args.device,
                                                 "--out", check.out / "predict" / "official.pfm"], timeout=300)
        figures["official"] = json.loads(out.strip().splitlines()[-1])
        theirs = read_pfm(check.out / "predict" / "official.pfm")
        figures["mbs_device_vs_official_mean_px"] = mean_abs_difference(maps[check.args.device], theirs)
    else:
        figures["official"] = {"not_run": f"no official code at {official}"}
    return figures


def autotune(check):
    """RAFT-Stereo's and IGEV-Stereo's steps with the autotune build, over
    the default build's from their phases."""
    binary = check.args.autotune_binary
    if binary is None:
        return {"not_run": "no autotune binary (prepare.sh --no-autotune, or no --autotune-binary)"}
    crop = "48x96" if check.args.small else "384x512"
    figures = {}
    for network in ("raft-stereo", "igev"):
        _, log, start = train(check, f"{network}-autotune", check.args.device, network, steps(check), crop,
                              timeout=420, binary=binary)
        tuned = {**step_figures(log, 2), "peak_gpu_mib": check.peak_gpu_mib(start)}
        default = check.results["phases"].get(network, {}).get("figures", {}).get("mbs", {})
        figures[network] = {"autotune": tuned, "default": default}
        if tuned.get("ms_per_step") and default.get("ms_per_step"):
            figures[network]["autotune_over_default"] = round(tuned["ms_per_step"] / default["ms_per_step"], 2)
    return figures


PHASES = [
    ("environment", environment, True),
    ("probe", probe, False),
    ("compact", compact, True),
    ("raft-stereo", network_step("raft-stereo"), True),
    ("igev", network_step("igev"), True),
    ("precision", precision, True),
    ("predict", predict, True),
    ("autotune", autotune, True),
]


def table(results):
    """The results as a short table; a phase kept from an earlier run says
    which."""
    lines = [f"GPU check on {results['device']}{' (small)' if results['small'] else ''}"]
    latest = results["runs"][-1]["run"]
    for name, phase in results["phases"].items():
        status = phase["status"]
        detail = ""
        figures = phase.get("figures", {})
        if name in ("raft-stereo", "igev") and status == "ok":
            ours, theirs = figures["mbs"], figures["official"]
            detail = (f"mbs {ours.get('ms_per_step')} ms/step, peak {ours.get('peak_gpu_mib')} MiB; official "
                      f"{theirs.get('ms_per_step', theirs.get('not_run'))}")
        elif name == "compact" and status == "ok":
            detail = (f"loss within {figures['loss_relative_error']:.1e}, gradient norm within "
                      f"{figures['grad_norm_relative_error']:.1e} of the CPU")
        elif name == "autotune" and status == "ok":
            detail = figures.get("not_run") or ", ".join(
                f"{n} {f['autotune'].get('ms_per_step')} ms/step"
                + (f" ({f['autotune_over_default']}x default)" if "autotune_over_default" in f else "")
                for n, f in figures.items())
        elif name == "predict" and status == "ok":
            detail = f"device vs CPU {figures['mbs_device_vs_cpu_mean_px']:.2e} px"
        elif status != "ok":
            detail = phase.get("error", "").splitlines()[0]
        earlier = f"(run {phase.get('run', 1)}) " if phase.get("run", 1) != latest else ""
        lines.append(f"  {name:12} {status:8} {phase.get('seconds', 0):6.1f} s  {earlier}{detail}")
    return "\n".join(lines)


class UnpackError(Exception):
    """An archive that cannot be unpacked, or a binary in the way."""


def unpacked(name):
    """The binary `name` beside this script; None when neither it nor
    `name.xz` is there. With `name.xz` there, the binary is the archive's
    complete unpack: made under a temporary name beside it, checked
    (decompressed to the end with the archive's own checksum, not empty,
    executable) and renamed, with a stamp (`.name.unpacked`) recording the
    archive and the binary it gave. A binary without a matching stamp (an
    older run.py's interrupted unpack, or an older archive's) is replaced
    when it is a part of the archive's content or was unpacked by run.py,
    kept when it is that content, and otherwise left alone (UnpackError)."""
    binary, packed = HERE / name, HERE / f"{name}.xz"
    if not packed.is_file():
        return binary if binary.is_file() else None
    stamp = HERE / f".{name}.unpacked"
    writable(stamp, other="pass --binary/--autotune-binary")
    try:
        recorded = json.loads(stamp.read_text())
    except (OSError, ValueError):
        recorded = {}
    if binary.is_file() and recorded == {"archive": identity(packed), "binary": identity(binary)}:
        return binary
    made_by_us = binary.is_file() and recorded.get("binary") == identity(binary)
    descriptor, temporary = tempfile.mkstemp(dir=HERE, prefix=f".{name}.", suffix=".unpacking")
    temporary = Path(temporary)
    try:
        try:
            with os.fdopen(descriptor, "wb") as target, lzma.open(packed) as source:
                shutil.copyfileobj(source, target, 1 << 20)
                target.flush()
                os.fsync(target.fileno())
        except EOFError as error:
            raise UnpackError(f"{packed}: truncated archive ({error})") from None
        except lzma.LZMAError as error:
            raise UnpackError(f"{packed}: corrupt archive ({error})") from None
        except OSError as error:
            raise UnpackError(f"{packed}: cannot unpack it beside itself ({error})") from None
        if temporary.stat().st_size == 0:
            raise UnpackError(f"{packed}: unpacks to an empty file")
        temporary.chmod(0o755)
        if binary.exists() or binary.is_symlink():
            if not binary.is_file() or binary.is_symlink():
                raise UnpackError(f"{binary} is in the way of unpacking {packed.name} and is not a file run.py "
                                  "made: move it away, or pass --binary/--autotune-binary")
            relation = compare(binary, temporary)
            if relation == "same":
                temporary.unlink()
            elif relation == "part" or made_by_us:
                os.replace(temporary, binary)
            else:
                raise UnpackError(f"{binary} is not {packed.name}'s content and run.py did not unpack it: move "
                                  "it away, or pass --binary/--autotune-binary")
        else:
            os.replace(temporary, binary)
        write_file(stamp, json.dumps({"archive": identity(packed), "binary": identity(binary)}) + "\n")
    except OSError as error:
        raise UnpackError(f"{packed}: cannot unpack it beside itself ({error})") from None
    finally:
        if temporary.exists():
            temporary.unlink()
    return binary


def identity(path):
    """A file's size and modification time (nanoseconds)."""
    status = path.stat()
    return [status.st_size, status.st_mtime_ns]


def compare(existing, complete):
    """Whether `existing` has the same bytes as `complete` ("same"), is a
    beginning of them ("part": an interrupted unpack), or neither ("other")."""
    with open(existing, "rb") as a, open(complete, "rb") as b:
        while True:
            chunk = a.read(1 << 20)
            if not chunk:
                return "same" if not b.read(1) else "part"
            if b.read(len(chunk)) != chunk:
                return "other"


def arguments():
    """The command line's parser."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True, help="folder for results.json, logs/ and samples; a "
                        "second run into it merges its phases into the results there (see above)")
    parser.add_argument("--device", default="cuda", help="cuda, cuda:N, vulkan or cpu (default cuda)")
    parser.add_argument("--binary", type=Path, help="mbs-tool to run (default: ./mbs-tool, unpacked from "
                        "mbs-tool.xz beside this script when needed)")
    parser.add_argument("--autotune-binary", type=Path, help="mbs-tool built with burn's autotune (default: "
                        "./mbs-tool-autotune, unpacked from mbs-tool-autotune.xz when there; none: the phase is "
                        "not run)")
    parser.add_argument("--small", action="store_true", help="small sizes (CI on the CPU)")
    parser.add_argument("--phases", help="comma-separated subset of: " + ", ".join(n for n, _, _ in PHASES))
    return parser


def binaries(parser, args):
    """Sets args.binary and args.autotune_binary: the ones given, checked
    before anything is unpacked, or the ones beside this script."""
    for flag, given in [("--binary", args.binary), ("--autotune-binary", args.autotune_binary)]:
        if given is not None and not given.is_file():
            parser.error(f"{flag} {given}: no such file")
    args.binary = args.binary or unpacked("mbs-tool")
    if args.binary is None:
        parser.error(f"--binary {HERE / 'mbs-tool'}: no such file")
    args.autotune_binary = args.autotune_binary or unpacked("mbs-tool-autotune")
    args.binary = args.binary.resolve()
    args.autotune_binary = args.autotune_binary and args.autotune_binary.resolve()


def run_phases(check, wanted):
    """Runs the phases wanted (all when None; the environment and the probe
    always), recording each as it ends; whether one failed."""
    failed = False
    for name, phase, keep_going in PHASES:
        if wanted is not None and name not in wanted and name not in ("environment", "probe"):
            continue
        start = time.time()
        print(f"[{time.strftime('%H:%M:%S')}] {name} ...", flush=True)
        try:
            record = {"status": "ok", "figures": phase(check)}
        except PhaseError as error:
            record = {"status": "failed", "error": str(error)}
        except Exception as error:  # a bug of this script: recorded, the run goes on
            record = {"status": "failed", "error": f"{type(error).__name__}: {error}"}
        record["seconds"] = round(time.time() - start, 1)
        check.record(name, record)
        if record["status"] != "ok":
            failed = True
            print(record["error"], flush=True)
            if not keep_going:
                break
    return failed


def main():
    parser = arguments()
    args = parser.parse_args()
    wanted = set(args.phases.split(",")) if args.phases else None
    unknown = sorted((wanted or set()) - {name for name, _, _ in PHASES})
    if unknown:
        known = ", ".join(name for name, _, _ in PHASES)
        parser.error(f"--phases: no phase named {', '.join(unknown)} (the phases: {known})")
    try:
        previous, samples = check_output(args)
        binaries(parser, args)
        check = Check(args, previous)
    except (UnpackError, Refused, OSError) as error:
        print(f"run.py: {error}", file=sys.stderr)
        return 2
    if shutil.which("nvidia-smi"):
        check.sampler = GpuSampler(check.out / "gpu_samples.csv", samples)
        check.sampler.start()
    problems = []
    try:
        failed = run_phases(check, wanted)
    except Refused as error:  # a link put in the way during the run
        failed, problems = True, [str(error)]
    finally:
        problems += [check.sampler.finish()] if check.sampler else []
    for problem in filter(None, problems):
        print(f"run.py: {problem}", file=sys.stderr)
    print(table(check.results))
    return 1 if failed or any(problems) else 0


if __name__ == "__main__":
    sys.exit(main())
