//! Helpers shared by the end-to-end tests: running the binary, making data.

#![allow(dead_code)] // each test file uses a different subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use mbs_core::FloatImage;
use mbs_core::formats::{carla, rgb};

/// The `mbs-tool` binary built for these tests.
pub fn mbs_tool() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mbs-tool"))
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

/// Every file under `root` (relative path -> bytes), sorted.
pub fn tree(root: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files: Vec<(PathBuf, Vec<u8>)> = walkdir::WalkDir::new(root)
        .into_iter()
        .filter_map(Result::ok)
        .filter(|e| e.file_type().is_file())
        .map(|e| {
            let rel = e
                .path()
                .strip_prefix(root)
                .expect("under root")
                .to_path_buf();
            (rel, std::fs::read(e.path()).expect("read"))
        })
        .collect();
    files.sort();
    files
}
