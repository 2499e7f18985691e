//! Helpers shared by the end-to-end tests: running the binary, making data.

#![allow(dead_code)] // each test file uses a different subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use mbs_core::FloatImage;
use mbs_core::formats::{carla, rgb};

/// The `mbs-tool` binary built for these tests.
pub fn mbs_tool() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mbs-tool"))
}

/// `mpirun -np RANKS --oversubscribe` (this machine may have fewer cores;
/// `--allow-run-as-root` as root) with a session folder of its own under
/// `session`: Open MPI makes `$TMPDIR/ompi.HOST.UID` as it starts, and two
/// `mpirun`s starting at once in one folder (the tests run in parallel)
/// can race on it ("mkdir ... File exists", seen in CI). Keep `session`
/// short: Open MPI's sockets live below it.
pub fn mpirun(ranks: usize, session: &Path) -> Command {
    std::fs::create_dir_all(session).expect("the MPI session folder is created");
    let mut command = Command::new("mpirun");
    command.env("TMPDIR", session);
    command.args(["-np", &ranks.to_string(), "--oversubscribe"]);
    let root = Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
    if root {
        command.arg("--allow-run-as-root");
    }
    command
}

/// Runs `mbs-tool` with `args` and returns its output.
pub fn run(args: &[&str]) -> Output {
    mbs_tool().args(args).output().expect("mbs-tool starts")
}

/// Stdout and stderr of an output, for assertion messages.
pub fn text(output: &Output) -> String {
    format!(
        "status {:?}\n--- stdout\n{}\n--- stderr\n{}",
        output.status.code(),
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

/// A depth map with a near slanted ground, a box and sky, different per `seed`.
pub fn depth_map(width: u32, height: u32, seed: u32) -> FloatImage {
    FloatImage::from_fn(width, height, |x, y| {
        let v = y as f32 / height as f32;
        let u = x as f32 / width as f32;
        let z = if v < 0.4 {
            1000.0 // sky
        } else if (0.3..0.5).contains(&u) && v < 0.7 {
            8.0 + seed as f32 * 0.37
        } else {
            2.0 + 60.0 * (1.0 - v) + u * 3.0 + seed as f32 * 0.11
        };
        image::Luma([z])
    })
}

/// Writes `frames` CARLA depth PNGs in an MBS20K layout under `root` and
/// returns their paths.
pub fn write_carla_frames(root: &Path, frames: u32, width: u32, height: u32) -> Vec<PathBuf> {
    (0..frames)
        .map(|i| {
            let town = if i % 2 == 0 { "Town01" } else { "Town10" };
            let path = root.join(format!("{town}/ClearNoon/{i:06}/depth_0.png"));
            let encoded = carla::encode_depth(&depth_map(width, height, i));
            rgb::write_rgb_png(&path, &encoded).expect("write depth png");
            path
        })
        .collect()
}

/// A small synthetic training set (its manifest is returned): Town01 for training, Town10 held out.
pub fn synth(root: &Path) -> String {
    let out = root.display().to_string();
    let output = run(&[
        "synth",
        "--out",
        &out,
        "--frames",
        "2",
        "--towns",
        "Town01,Town10",
        "--weathers",
        "ClearNoon",
        "--width",
        "128",
        "--height",
        "64",
        "--focal",
        "64",
        "--no-checksums",
    ]);
    assert!(output.status.success(), "{}", text(&output));
    root.join("manifest.json").display().to_string()
}

/// Small, fast training settings.
pub const SMALL: [&str; 12] = [
    "--batch-size",
    "2",
    "--crop",
    "48x96",
    "--max-disparity",
    "32",
    "--set",
    "network.compact.features=8",
    "--set",
    "augment.occlusion_max_side=20",
    "--set",
    "augment.occlusion_min_side=5",
];

/// The JSON lines of a log.
pub fn lines(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .expect("the log is readable")
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect()
}

/// Runs `command` with a deadline: a read that blocks, or a run that does
/// not end, fails the test instead of hanging it.
pub fn within(mut command: Command, seconds: u64) -> Output {
    let mut child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the command starts");
    let start = Instant::now();
    while child
        .try_wait()
        .expect("the command is waited for")
        .is_none()
    {
        if start.elapsed() > Duration::from_secs(seconds) {
            let _ = child.kill();
            panic!("{command:?} still ran after {seconds} s (a blocked read?)");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child
        .wait_with_output()
        .expect("the command's output is read")
}

/// Asserts that `output` exits non-zero (not a panic) and says every one
/// of `words`.
pub fn refused(output: &Output, words: &[&str]) {
    let all = text(output);
    assert!(!output.status.success(), "{all}");
    assert_ne!(output.status.code(), Some(101), "panicked: {all}");
    for word in words {
        assert!(all.contains(word), "{word:?} not said: {all}");
    }
}
