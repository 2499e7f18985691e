//! `mbs-tool train` over the processes of an MPI job (`mpirun -np N`), as a
//! user launches it: the ranks train the weights one process trains, rank 0
//! alone writes the run, checkpoints resume on any number of ranks, a killed
//! rank ends the job, and ranks that disagree are refused before anything
//! is written.
//!
//! These need the binary built with `--features mpi` and Open MPI's
//! `mpirun`; `tools/test.sh` provides both (it tests the workspace with
//! `--features mbs-tool/mpi`). Without them they fail, never skip: a
//! binary without MPI refuses to run under `mpirun`.

mod common;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use burn::tensor::Device;
use common::{SMALL, lines, synth, text};
use mbs_nets::checkpoint::TrainedNetworks;
use mbs_test_support::files::complete_lines;

/// Settings of every run here: SMALL's tiny compact network at batch 3,
/// so that 2 ranks share it unevenly (2 + 1 items) and 3 ranks evenly.
fn settings(steps: usize) -> Vec<String> {
    let mut args: Vec<String> = SMALL.iter().map(|s| s.to_string()).collect();
    args[1] = "3".into(); // --batch-size
    let steps = steps.to_string();
    args.extend(
        [
            "--steps",
            &steps,
            "--val-every",
            "2",
            "--checkpoint-every",
            "2",
            "--jobs",
            "1",
            "--set",
            "log_every=1",
            "--set",
            "keep_checkpoints=5",
        ]
        .map(String::from),
    );
    args
}

fn train_args(manifest: &str, out: &Path, steps: usize) -> Vec<String> {
    let mut args = vec![
        "train".to_string(),
        manifest.to_string(),
        "--out".into(),
        out.display().to_string(),
    ];
    args.extend(settings(steps));
    args
}

/// Trains into `out` on `ranks` processes (1: without mpirun).
fn train(ranks: usize, manifest: &str, out: &Path, steps: usize) -> Output {
    train_with(ranks, manifest, out, steps, &[])
}

/// [`train`] with `extra` flags after the common ones.
fn train_with(ranks: usize, manifest: &str, out: &Path, steps: usize, extra: &[&str]) -> Output {
    let output = match ranks {
        1 => common::mbs_tool()
            .args(train_args(manifest, out, steps))
            .args(extra)
            .output(),
        _ => common::mpirun(ranks, &out.with_extension("ompi"))
            .arg(env!("CARGO_BIN_EXE_mbs-tool"))
            .args(train_args(manifest, out, steps))
            .args(extra)
            .output(),
    }
    .expect("the run starts (tools/test.sh installs Open MPI's mpirun)");
    assert!(output.status.success(), "{ranks} ranks: {}", text(&output));
    output
}

/// The files of a run, relative to it; TensorBoard's event files counted,
/// since their names carry the host and the time.
fn files(dir: &Path) -> BTreeSet<String> {
    walk(dir)
        .into_iter()
        .map(|path| {
            let name = path
                .strip_prefix(dir)
                .expect("inside")
                .display()
                .to_string();
            match name.starts_with("tensorboard/") {
                true => "tensorboard/<events>".into(),
                false => name,
            }
        })
        .collect()
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).expect("readable") {
        let path = entry.expect("entry").path();
        if path.is_dir() {
            out.extend(walk(&path));
        } else {
            out.push(path);
        }
    }
    out
}

/// Student and teacher weights of a run's checkpoint after `steps`.
fn weights(run: &Path, steps: usize) -> Vec<f32> {
    let dir = run.join(format!("checkpoints/step-{steps:07}"));
    let networks = TrainedNetworks::open(&dir).expect("a checkpoint");
    let device = Device::flex();
    let mut values = Vec::new();
    for network in [networks.student(&device), networks.teacher(&device)] {
        let (state, _) = network.expect("loads").state_dict();
        for tensor in state.tensors.into_values() {
            values.extend(tensor.values);
        }
    }
    values
}

/// The largest difference between two runs' weights after `steps`.
fn weight_difference(a: &Path, b: &Path, steps: usize) -> f32 {
    let (a, b) = (weights(a, steps), weights(b, steps));
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// The losses a run logged, step by step.
fn losses(run: &Path) -> Vec<(u64, f64)> {
    // The ranks may be writing the log: a last line still being written is
    // left out (reading it half-written failed a CI run under load).
    complete_lines(&run.join("train.jsonl"))
        .iter()
        .map(|line| serde_json::from_str::<serde_json::Value>(line).expect("a JSON line"))
        .map(|line| {
            (
                line["step"].as_u64().expect("step"),
                line["loss"].as_f64().expect("loss"),
            )
        })
        .collect()
}

fn assert_same_losses(a: &Path, b: &Path) {
    let (a, b) = (losses(a), losses(b));
    assert_eq!(a.len(), b.len(), "{a:?} {b:?}");
    for ((step_a, loss_a), (step_b, loss_b)) in a.iter().zip(&b) {
        assert_eq!(step_a, step_b);
        assert!(
            (loss_a - loss_b).abs() <= 1e-4 * loss_a.abs(),
            "step {step_a}: {loss_a} and {loss_b}"
        );
    }
}

/// Copies a finished run without its last checkpoint, as if it had been
/// stopped after the one before.
fn cut_back(run: &Path, to: &Path, last: usize) {
    let status = Command::new("cp")
        .arg("-r")
        .arg(run)
        .arg(to)
        .status()
        .expect("cp");
    assert!(status.success());
    std::fs::remove_dir_all(to.join(format!("checkpoints/step-{last:07}"))).expect("remove");
}

/// Weights equal within float summation order: 2 and 3 ranks sum the
/// shares' gradients in another order than one process computes the whole
/// batch's. After 4 Adam steps the compact network's weights were within
/// 5.7e-7 (2 ranks) and 4.5e-8 (3 ranks) of the one-process run's when
/// written; a wrong share or weighting moves them by about the learning
/// rate (2e-4).
const WEIGHT_TOLERANCE: f32 = 2e-5;

#[test]
fn two_and_three_ranks_train_what_one_process_trains_and_resume_on_any_count() {
    let dir = tempfile::tempdir().expect("temp dir");
    let manifest = synth(&dir.path().join("data"));
    let run = |name: &str| dir.path().join(name);
    let one = train(1, &manifest, &run("one"), 4);
    let two = train(2, &manifest, &run("two"), 4);
    train(3, &manifest, &run("three"), 4);
    assert!(
        String::from_utf8_lossy(&two.stderr).contains("on 2 processes"),
        "{}",
        text(&two)
    );
    for ranks in ["two", "three"] {
        let worst = weight_difference(&run("one"), &run(ranks), 4);
        println!("{ranks} ranks: weights within {worst} of one process's");
        assert!(worst <= WEIGHT_TOLERANCE, "{ranks}: {worst}");
        assert_same_losses(&run("one"), &run(ranks));
        // Rank 0 alone wrote: the same files as one process, each once.
        assert_eq!(files(&run("one")), files(&run(ranks)), "{ranks}");
        let validations: Vec<u64> = lines(&run(ranks).join("val.jsonl"))
            .iter()
            .map(|l| l["step"].as_u64().expect("step"))
            .collect();
        assert_eq!(validations, [0, 2, 4], "{ranks}");
    }
    // The summary is printed once.
    let summary = |output: &Output| {
        String::from_utf8_lossy(&output.stderr)
            .matches("Outputs in")
            .count()
    };
    assert_eq!(summary(&one), 1);
    assert_eq!(summary(&two), 1, "{}", text(&two));

    // A checkpoint of 2 ranks resumes on one process, and one of one
    // process on 2 ranks, each as the uninterrupted run goes on.
    cut_back(&run("two"), &run("two-then-one"), 4);
    let resumed = train(1, &manifest, &run("two-then-one"), 4);
    assert!(
        String::from_utf8_lossy(&resumed.stderr).contains("resuming"),
        "{}",
        text(&resumed)
    );
    cut_back(&run("one"), &run("one-then-two"), 4);
    let resumed = train(2, &manifest, &run("one-then-two"), 4);
    assert!(
        String::from_utf8_lossy(&resumed.stderr).contains("at step 2 of 4 on 2 processes"),
        "{}",
        text(&resumed)
    );
    for name in ["two-then-one", "one-then-two"] {
        assert_same_losses(&run("one"), &run(name));
        let worst = weight_difference(&run("one"), &run(name), 4);
        assert!(worst <= WEIGHT_TOLERANCE, "{name}: {worst}");
    }
}

/// Ranks of two CPU devices each train what one process trains: a batch of
/// 5 is dealt 3 + 2 to the ranks and split again 2 + 1 and 1 + 1 over
/// their devices, each share weighted by its part of the 5 items; the
/// devices' gradients are summed in the rank, then over the ranks.
#[test]
fn ranks_of_two_devices_each_train_what_one_process_trains() {
    let dir = tempfile::tempdir().expect("temp dir");
    let manifest = synth(&dir.path().join("data"));
    let run = |name: &str| dir.path().join(name);
    let batch = ["--set", "data.batch_size=5"];
    train_with(1, &manifest, &run("one"), 4, &batch);
    let devices = ["--set", "data.batch_size=5", "--device", "cpu,cpu"];
    let two = train_with(2, &manifest, &run("two-by-two"), 4, &devices);
    assert!(
        String::from_utf8_lossy(&two.stderr).contains("on 2 processes"),
        "{}",
        text(&two)
    );
    let worst = weight_difference(&run("one"), &run("two-by-two"), 4);
    println!("2 ranks of 2 devices: weights within {worst} of one process's");
    assert!(worst <= WEIGHT_TOLERANCE, "{worst}");
    assert_same_losses(&run("one"), &run("two-by-two"));
    assert_eq!(files(&run("one")), files(&run("two-by-two")));
}

/// The processes whose command lines train into `out` (mpirun's too).
fn processes_writing(out: &Path) -> Vec<u32> {
    let listed = Command::new("pgrep")
        .args(["-f", &format!("mbs-tool train .* --out {}", out.display())])
        .output()
        .expect("pgrep runs");
    String::from_utf8_lossy(&listed.stdout)
        .lines()
        .filter_map(|pid| pid.trim().parse().ok())
        .collect()
}

/// Seconds within which the other ranks are gone once one is killed.
const KILL_BOUND: Duration = Duration::from_secs(30);

/// The exit status of `job`, which must end within [`KILL_BOUND`] (`when`
/// says after what, for the failure message).
fn exit_within(job: &mut std::process::Child, when: &str) -> std::process::ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(status) = job.try_wait().expect("wait") {
            return status;
        }
        assert!(
            start.elapsed() < KILL_BOUND,
            "mpirun still runs {KILL_BOUND:?} {when}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn a_killed_rank_ends_every_rank_sigusr1_stops_them_and_the_same_command_resumes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let manifest = synth(&dir.path().join("data"));
    let out = dir.path().join("killed");
    // Long enough that SIGUSR1 (below) lands before the end.
    let steps = 150;
    a_killed_rank_ends_every_rank(&manifest, &out, steps);
    let newest = newest_checkpoint(&out, steps);
    let last_logged = sigusr1_stops_every_rank_at_a_checkpoint(&manifest, &out, steps, newest);
    the_same_command_resumes_and_logs_each_step_once(&manifest, &out, steps, last_logged);
}

/// Trains `steps` into `out` on 2 ranks and kills one (-9) once the step-4
/// checkpoint is written: the job ends within [`KILL_BOUND`], reports the
/// failure, and leaves no rank.
fn a_killed_rank_ends_every_rank(manifest: &str, out: &Path, steps: usize) {
    let mut job = common::mpirun(2, &out.with_extension("ompi"))
        .arg(env!("CARGO_BIN_EXE_mbs-tool"))
        .args(train_args(manifest, out, steps))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mpirun starts (tools/test.sh installs Open MPI)");
    let start = Instant::now();
    while !out.join("checkpoints/step-0000004").exists() {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no checkpoint after 2 minutes"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let ranks: Vec<u32> = processes_writing(out)
        .into_iter()
        .filter(|pid| *pid != job.id())
        .collect();
    assert_eq!(ranks.len(), 2, "{ranks:?}");
    let killed = Command::new("kill")
        .args(["-9", &ranks[1].to_string()])
        .status()
        .expect("kill");
    assert!(killed.success());
    let killed_at = Instant::now();
    let status = exit_within(&mut job, "after a rank was killed");
    let ended_in = killed_at.elapsed();
    println!("every rank ended {ended_in:?} after one was killed");
    assert!(!status.success(), "the job reports the failure");
    assert!(processes_writing(out).is_empty(), "no rank is left");
}

/// The step of the newest checkpoint of the run in `out`, saved before the
/// end (`steps`).
fn newest_checkpoint(out: &Path, steps: usize) -> usize {
    let saved: Vec<usize> = std::fs::read_dir(out.join("checkpoints"))
        .expect("checkpoints")
        .filter_map(|e| {
            let name = e.ok()?.file_name().to_string_lossy().to_string();
            name.strip_prefix("step-")?.parse().ok()
        })
        .collect();
    let newest = *saved.iter().max().expect("a checkpoint");
    assert!(newest < steps, "killed before the end: {saved:?}");
    newest
}

/// Resumes the run in `out` (its `newest` checkpoint is whole) on 2 ranks
/// and sends SIGUSR1 to mpirun, which forwards it to every rank at once:
/// every rank stops at the same step, rank 0 saves a checkpoint there, the
/// job fails. Returns that step. (Ctrl-C reaches the ranks as SIGTERM only
/// after mpirun's `odls_base_sigkill_timeout`, 1 s, and SIGKILL a second
/// later: the checkpoint then depends on how loaded the machine is.)
fn sigusr1_stops_every_rank_at_a_checkpoint(
    manifest: &str,
    out: &Path,
    steps: usize,
    newest: usize,
) -> u64 {
    // The killed run may have logged steps past its newest checkpoint:
    // only a step past those was logged by the resumed ranks, whose
    // handlers are then installed (SIGUSR1 before that ends a process).
    let logged_before = losses(out).last().map_or(0, |(step, _)| *step);
    let resumed_from = logged_before.max(newest as u64 + 1);
    let mut job = common::mpirun(2, &out.with_extension("ompi"))
        .arg(env!("CARGO_BIN_EXE_mbs-tool"))
        .args(train_args(manifest, out, steps))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("mpirun starts");
    let resumed_at = Instant::now();
    while losses(out)
        .last()
        .is_none_or(|(step, _)| *step <= resumed_from)
    {
        assert!(
            resumed_at.elapsed() < Duration::from_secs(120),
            "did not resume"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let signalled = Command::new("kill")
        .args(["-USR1", &job.id().to_string()])
        .status()
        .expect("kill");
    assert!(signalled.success());
    let status = exit_within(&mut job, "after SIGUSR1");
    assert!(!status.success());
    assert!(processes_writing(out).is_empty(), "no rank is left");
    let (last_logged, _) = *losses(out).last().expect("logged");
    assert!(last_logged < steps as u64, "stopped before the end");
    assert!(
        out.join(format!("checkpoints/step-{last_logged:07}"))
            .exists(),
        "a checkpoint at the step the ranks stopped at ({last_logged})"
    );
    last_logged
}

/// The same command resumes the run in `out` at the step the ranks
/// stopped at, `last_logged`, and finishes, each of its `steps` logged
/// once.
fn the_same_command_resumes_and_logs_each_step_once(
    manifest: &str,
    out: &Path,
    steps: usize,
    last_logged: u64,
) {
    let output = train(2, manifest, out, steps);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let resumed = format!(
        "resuming {} at step {last_logged} of {steps} on 2 processes",
        out.display()
    );
    assert!(stderr.contains(&resumed), "{stderr}");
    let logged: Vec<u64> = losses(out).iter().map(|(step, _)| *step).collect();
    assert_eq!(
        logged,
        (1..=steps as u64).collect::<Vec<_>>(),
        "each step logged once"
    );
}

/// An MPMD launch (`mpirun -np 1 A : -np 1 B`): two ranks given different
/// command lines.
fn mismatched(manifest: &str, out: &Path, rank_one_extra: &[&str]) -> Output {
    let binary = env!("CARGO_BIN_EXE_mbs-tool");
    let mut command = common::mpirun(1, &out.with_extension("ompi"));
    command
        .arg(binary)
        .args(train_args(manifest, out, 4))
        .args([":", "-np", "1", binary])
        .args(train_args(manifest, out, 4))
        .args(rank_one_extra);
    command.output().expect("mpirun starts")
}

#[test]
fn ranks_that_disagree_or_cannot_open_their_device_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().expect("temp dir");
    let manifest = synth(&dir.path().join("data"));
    let out = dir.path().join("refused");

    let output = mismatched(&manifest, &out, &["--lr", "0.001"]);
    assert!(!output.status.success(), "{}", text(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    let expected = "settings.trainer.lr.max_lr is 0.001 on rank 1 and 0.0002 on rank 0";
    assert_eq!(
        stderr.matches(expected).count(),
        1,
        "printed once: {stderr}"
    );
    assert!(!out.exists(), "nothing was written");

    let output = mismatched(&manifest, &out, &["--device", "cuda:5"]);
    assert!(!output.status.success(), "{}", text(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(
        stderr
            .matches("error: rank 1 of 2: device `cuda:5`")
            .count(),
        1,
        "one line names the rank and its device: {stderr}"
    );
    assert!(!out.exists(), "nothing was written");
}

/// Launcher variables that say rank 0 and 1 of 2 with no MPI job behind
/// them used to make each process train alone into the same folder (its
/// world of one): now each is refused, naming the variables, before the
/// folder is made.
#[test]
fn launcher_variables_without_their_mpi_job_are_refused() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let manifest = synth(&dir.path().join("data"));
    let out = dir.path().join("run");
    let launchers: [&[(&str, &str)]; 2] = [
        &[("SLURM_PROCID", "1"), ("SLURM_STEP_NUM_TASKS", "2")],
        &[("OMPI_COMM_WORLD_RANK", "0"), ("OMPI_COMM_WORLD_SIZE", "2")],
    ];
    for variables in launchers {
        let output = common::mbs_tool()
            .args(train_args(&manifest, &out, 2))
            .envs(variables.iter().copied())
            .output()
            .expect("mbs-tool starts");
        let all = text(&output);
        assert!(!output.status.success(), "{all}");
        for (name, value) in variables {
            assert!(all.contains(&format!("{name}={value}")), "{all}");
        }
        assert!(all.contains("MPI gives this process a job of 1"), "{all}");
        assert!(!out.exists(), "the folder was made: {all}");
    }
}
