//! End-to-end tests of `mbs-tool decode-depth` on CARLA depth PNGs on disk.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::{run, text, write_carla_frames};
use mbs_core::formats::{exr, pfm, png16};
use mbs_test_support::files::{file_count, tree};

#[test]
fn decodes_depth_and_disparity_with_invalid_far_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let out = dir.path().join("out");
    write_carla_frames(&data, 2, 64, 48);
    let output = run(&[
        "decode-depth",
        data.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--pairs",
        "0:1,0:4",
    ]);
    assert!(output.status.success(), "{}", text(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("2 done, 0 skipped, 0 failed"), "{stderr}");

    let frame = out.join("Town01/ClearNoon/000000");
    let depth = exr::read_exr(&frame.join("depth_0.exr")).unwrap();
    let expected = common::depth_map(64, 48, 0);
    // Row 40: ground, about 2 + 60 * (1 - 40/48) + u * 3 metres.
    let (x, y) = (10, 40);
    let z = expected.get_pixel(x, y).0[0];
    assert!((depth.get_pixel(x, y).0[0] - z).abs() < 1e-4);
    assert_eq!(
        depth.get_pixel(x, 0).0[0],
        f32::INFINITY,
        "sky is beyond 200 m"
    );

    // Pair 0:4 is four baselines: d = 480 * 2.0 / z.
    let disp = png16::read_kitti_disparity(&frame.join("disp_0_4.png")).unwrap();
    assert!((disp.get_pixel(x, y).0[0] - 960.0 / z).abs() <= 0.5 / 256.0 + 1e-3);
    assert_eq!(disp.get_pixel(x, 0).0[0], f32::INFINITY);
    assert!(frame.join("disp_0_1.png").is_file());
    assert!(!frame.join("disp_0_2.png").exists());

    // A second run skips everything.
    let again = run(&[
        "decode-depth",
        data.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--pairs",
        "0:1,0:4",
    ]);
    assert!(
        String::from_utf8_lossy(&again.stderr).contains("0 done, 2 skipped"),
        "{}",
        text(&again)
    );
}

#[test]
fn pfm_outputs_and_sharding() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    write_carla_frames(&data, 4, 32, 24);
    let output = run(&[
        "decode-depth",
        data.to_str().unwrap(),
        "--depth-format",
        "pfm",
        "--disparity-format",
        "pfm",
        "--all-pairs",
        "--shard",
        "1/2",
    ]);
    assert!(output.status.success(), "{}", text(&output));
    // Sorted frames: Town01/000000, Town01/000002, Town10/000001, Town10/000003; shard 1/2 takes the 2nd and 4th.
    assert!(data.join("Town01/ClearNoon/000002/depth_0.pfm").is_file());
    assert!(data.join("Town10/ClearNoon/000003/disp_0_3.pfm").is_file());
    assert!(!data.join("Town01/ClearNoon/000000/depth_0.pfm").exists());
    let disp = pfm::read_pfm_grey(&data.join("Town01/ClearNoon/000002/disp_0_2.pfm")).unwrap();
    let z = common::depth_map(32, 24, 2).get_pixel(5, 20).0[0];
    assert!((disp.get_pixel(5, 20).0[0] - 480.0 / z).abs() < 1e-3);
}

#[test]
fn bad_inputs_give_clear_errors_and_non_zero_exit() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let frames = write_carla_frames(&data, 3, 16, 12);
    // A 16-bit PNG where an 8-bit RGB CARLA depth is expected, and a truncated one.
    png16::write_depth_mm(&frames[1], &common::depth_map(16, 12, 1)).unwrap();
    let bytes = std::fs::read(&frames[2]).unwrap();
    std::fs::write(&frames[2], &bytes[..bytes.len() / 2]).unwrap();
    let output = run(&["decode-depth", data.to_str().unwrap()]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("1 done, 0 skipped, 2 failed"), "{stderr}");
    assert!(
        stderr.contains("000001/depth_0.png") && stderr.contains("expected 8-bit RGB"),
        "{stderr}"
    );
    assert!(stderr.contains("000002/depth_0.png"), "{stderr}");
    assert!(
        !frames[2].with_file_name("depth_0.exr").exists(),
        "no output for a broken input"
    );

    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let output = run(&["decode-depth", empty.to_str().unwrap()]);
    assert!(!output.status.success());
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("no depth_0.png found"),
        "{}",
        text(&output)
    );

    let output = run(&[
        "decode-depth",
        data.to_str().unwrap(),
        "--depth-format",
        "png16",
    ]);
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("--max-depth 65 or less"),
        "{}",
        text(&output)
    );
    let output = run(&["decode-depth", data.to_str().unwrap(), "--pairs", "1:2"]);
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("reference must be 0"),
        "{}",
        text(&output)
    );
    let output = run(&["decode-depth", data.to_str().unwrap(), "--shard", "2/2"]);
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("expected K/N"),
        "{}",
        text(&output)
    );
}

#[test]
fn killed_run_resumes_to_byte_identical_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    write_carla_frames(&data, 80, 320, 240);
    let args = |out: &std::path::Path| {
        vec![
            "decode-depth".to_string(),
            data.to_str().unwrap().to_string(),
            "--out".into(),
            out.to_str().unwrap().to_string(),
            "--all-pairs".into(),
            "--disparity-format".into(),
            "pfm".into(),
            "--jobs".into(),
            "1".into(),
        ]
    };
    let clean = dir.path().join("clean");
    let output = common::mbs_tool().args(args(&clean)).output().unwrap();
    assert!(output.status.success(), "{}", text(&output));
    let reference = tree(&clean);
    assert_eq!(reference.len(), 80 * 5);

    // Kill a second run as soon as it has written something.
    let killed = dir.path().join("killed");
    let mut child = common::mbs_tool().args(args(&killed)).spawn().unwrap();
    let start = Instant::now();
    // Only count files while the child writes: reading them could meet a
    // temporary name just renamed.
    while file_count(&killed) == 0 && start.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let partial = tree(&killed);
    assert!(
        partial.len() < reference.len(),
        "the run was killed before the end"
    );
    for (path, bytes) in &partial {
        let name = path.to_string_lossy();
        if name.ends_with(".partial") {
            continue; // a temporary name that no reader trusts and a re-run overwrites
        }
        let expected = reference.iter().find(|(p, _)| p == path).map(|(_, b)| b);
        assert_eq!(expected, Some(bytes), "{name} differs from the clean run");
    }

    let output = common::mbs_tool().args(args(&killed)).output().unwrap();
    assert!(output.status.success(), "{}", text(&output));
    assert_eq!(
        tree(&killed),
        reference,
        "resumed run equals a clean run, no partial file left"
    );
}

/// `--shard auto` under Open MPI's `mpirun` (3 ranks) and as 3 tasks of
/// an `srun` step (SLURM's variables): together the shards write exactly
/// the unsharded run's files. Without a launcher, `auto` is a usage error.
/// Open MPI comes from `tools/test.sh`; without `mpirun` this test fails.
#[test]
fn shard_auto_under_mpirun_and_srun_equals_the_unsharded_run() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    write_carla_frames(&data, 6, 32, 24);
    let unsharded = common::mbs_tool()
        .args(decode_all_pairs(&data, &dir.path().join("whole")))
        .output()
        .unwrap();
    assert!(unsharded.status.success(), "{}", text(&unsharded));
    let whole = tree(&dir.path().join("whole"));
    assert!(whole.len() >= 6 * 5, "{} files", whole.len());

    mpirun_ranks_write_the_unsharded_files(dir.path(), &data, &whole);
    srun_tasks_write_the_unsharded_files(dir.path(), &data, &whole);
    one_srun_task_alone_writes_its_third(dir.path(), &data, &whole);
    without_a_launcher_auto_is_a_usage_error(dir.path(), &data);
}

/// The environment variables by which a launcher (Open MPI, MPICH's PMI,
/// SLURM) tells a process its shard.
const LAUNCHERS: [&str; 8] = [
    "OMPI_COMM_WORLD_RANK",
    "OMPI_COMM_WORLD_SIZE",
    "PMI_RANK",
    "PMI_SIZE",
    "SLURM_PROCID",
    "SLURM_STEP_NUM_TASKS",
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_COUNT",
];

/// The arguments of `decode-depth DATA --all-pairs --out OUT`.
fn decode_all_pairs(data: &Path, out: &Path) -> Vec<String> {
    let (data, out) = (data.display().to_string(), out.display().to_string());
    vec![
        "decode-depth".into(),
        data,
        "--all-pairs".into(),
        "--out".into(),
        out,
    ]
}

/// `--shard auto` on 3 ranks of `mpirun` into `dir/mpirun`: each rank
/// decodes its 2 of the 6 frames of `data`, and together they write the
/// unsharded run's files, `whole`.
fn mpirun_ranks_write_the_unsharded_files(dir: &Path, data: &Path, whole: &[(PathBuf, Vec<u8>)]) {
    let output = common::mpirun(3, &dir.join("ompi"))
        .arg(env!("CARGO_BIN_EXE_mbs-tool"))
        .args(decode_all_pairs(data, &dir.join("mpirun")))
        .args(["--shard", "auto"])
        .output()
        .expect("mpirun runs (tools/test.sh installs Open MPI)");
    assert!(output.status.success(), "{}", text(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(stderr.matches(": 2 done, 0 skipped").count(), 3, "{stderr}");
    assert_eq!(tree(&dir.join("mpirun")), whole);
}

/// `--shard auto` as 3 tasks of an `srun` step (SLURM's variables) into
/// `dir/srun`: together they write the unsharded run's files, `whole`.
fn srun_tasks_write_the_unsharded_files(dir: &Path, data: &Path, whole: &[(PathBuf, Vec<u8>)]) {
    let tasks: Vec<_> = (0..3)
        .map(|task| {
            common::mbs_tool()
                .args(decode_all_pairs(data, &dir.join("srun")))
                .args(["--shard", "auto"])
                .env("SLURM_PROCID", task.to_string())
                .env("SLURM_STEP_NUM_TASKS", "3")
                .spawn()
                .unwrap()
        })
        .collect();
    for task in tasks {
        let output = task.wait_with_output().unwrap();
        assert!(output.status.success(), "{}", text(&output));
    }
    assert_eq!(tree(&dir.join("srun")), whole);
}

/// One `srun` task of 3 alone writes its third of the unsharded run's
/// files, `whole`.
fn one_srun_task_alone_writes_its_third(dir: &Path, data: &Path, whole: &[(PathBuf, Vec<u8>)]) {
    let output = common::mbs_tool()
        .args(decode_all_pairs(data, &dir.join("one")))
        .args(["--shard", "auto"])
        .env("SLURM_PROCID", "1")
        .env("SLURM_STEP_NUM_TASKS", "3")
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", text(&output));
    assert_eq!(tree(&dir.join("one")).len() * 3, whole.len());
}

/// Without a launcher's variables, `--shard auto` is a usage error and
/// nothing is written.
fn without_a_launcher_auto_is_a_usage_error(dir: &Path, data: &Path) {
    let mut alone = common::mbs_tool();
    for name in LAUNCHERS {
        alone.env_remove(name);
    }
    let output = alone
        .args(decode_all_pairs(data, &dir.join("alone")))
        .args(["--shard", "auto"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(2), "{}", text(&output));
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("no launcher set this process's shard"),
        "{}",
        text(&output)
    );
    assert!(!dir.join("alone").exists());
}
