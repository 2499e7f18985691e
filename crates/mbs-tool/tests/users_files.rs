//! The user's files, in every command (issue 57), through `mbs-tool`
//! itself on copies of real Middlebury Teddy laid out as KITTI 2015, KITTI
//! 2012 and MiddEval3: one process writes a run or output folder at a
//! time (a `kill -9` releases it), inputs are indexed down to the file,
//! no output replaces a file mbs did not write, and `train --restart`
//! checks everything before it deletes. Every refused command leaves
//! every input byte-identical.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::{mbs_tool, refused, text, within};
use mbs_core::FloatImage;
use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_core::formats::{png16, read_disparity};
use mbs_test_support::files::tree;

const W: u32 = 96;
const H: u32 = 64;

fn teddy(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/middlebury-teddy")
        .join(file)
}

/// Teddy's view `file` (im2.png, im6.png), cropped, saved as `path`.
fn teddy_view(file: &str, path: &Path) {
    let view = image::open(teddy(file)).unwrap().into_rgb8();
    let view = image::imageops::crop_imm(&view, 200, 150, W, H).to_image();
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    view.save(path).unwrap();
}

/// Teddy's left-view ground truth, cropped (`inf` where unknown).
fn teddy_truth() -> FloatImage {
    let gt = read_disparity(&teddy("disp2.png"), Some(4.0)).unwrap();
    image::imageops::crop_imm(&gt, 200, 150, W, H).to_image()
}

/// A KITTI split `root/folder` of one frame: Teddy's views in `views`,
/// its ground truth in each of `truths`.
fn kitti(root: &Path, folder: &str, views: [&str; 2], truths: [&str; 3]) -> PathBuf {
    let dir = root.join(folder);
    teddy_view("im2.png", &dir.join(views[0]).join("000000_10.png"));
    teddy_view("im6.png", &dir.join(views[1]).join("000000_10.png"));
    for truth in truths {
        let path = dir.join(truth).join("000000_10.png");
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        png16::write_kitti_disparity(&path, &teddy_truth()).unwrap();
    }
    dir
}

/// A KITTI 2015 split of one frame with both views' ground truth.
fn kitti_2015(root: &Path) -> PathBuf {
    let truths = ["disp_occ_0", "disp_noc_0", "disp_occ_1"];
    kitti(root, "kitti2015/training", ["image_2", "image_3"], truths)
}

/// A KITTI 2012 split of one frame, with its reflective-surface truth.
fn kitti_2012(root: &Path) -> PathBuf {
    let truths = ["disp_occ", "disp_noc", "disp_refl_occ"];
    kitti(
        root,
        "kitti2012/training",
        ["colored_0", "colored_1"],
        truths,
    )
}

/// A MiddEval3 root with `trainingQ/Teddy`, whose ground truth includes a
/// `disp0GTy.pfm` (a name `submit --name GTy` would write).
fn middeval3(root: &Path) -> PathBuf {
    let scene = root.join("MiddEval3/trainingQ/Teddy");
    teddy_view("im2.png", &scene.join("im0.png"));
    teddy_view("im6.png", &scene.join("im1.png"));
    for name in ["disp0GT.pfm", "disp0GTy.pfm"] {
        write_pfm_grey(&scene.join(name), &teddy_truth(), Endian::Little).unwrap();
    }
    std::fs::write(scene.join("calib.txt"), "ndisp=64\n").unwrap();
    root.join("MiddEval3")
}

/// Fails, naming the files that differ, unless `after` equals `before`
/// (two listings from `tree`, which leaves out mbs's lock files: a refused
/// `train` names itself in the lock of the folder it took first).
fn unchanged(before: &Files, after: &Files, what: &str) {
    let differing: Vec<String> = before
        .iter()
        .chain(after)
        .filter(|file| !before.contains(file) || !after.contains(file))
        .map(|(path, _)| path.display().to_string())
        .collect();
    assert!(differing.is_empty(), "{what}: {differing:?}");
}

/// A folder's files and their bytes, as `tree` lists them.
type Files = Vec<(PathBuf, Vec<u8>)>;

fn succeeded(output: &Output) {
    assert!(output.status.success(), "{}", text(output));
}

/// `submit --middlebury --name GTy`, `submit --kitti` (2012) into
/// `disp_refl_occ` and `predict --kitti --out disp_occ_1`, with or without
/// `--overwrite` (`flag`): each would write over a dataset file.
fn over_dataset_files(middlebury: &Path, k12: &Path, k15: &Path, flag: &[&str]) -> [Output; 3] {
    let submit_middlebury = mbs_tool()
        .args(["submit", "--middlebury"])
        .arg(middlebury.join("trainingQ"))
        .args(["--name", "GTy", "--out"])
        .arg(middlebury)
        .args(flag)
        .output()
        .unwrap();
    let submit_kitti = mbs_tool()
        .arg("submit")
        .arg("--kitti")
        .arg(k12)
        .arg("--out")
        .arg(k12.join("disp_refl_occ"))
        .args(flag)
        .output()
        .unwrap();
    let predict = mbs_tool()
        .arg("predict")
        .arg("--kitti")
        .arg(k15)
        .args(["--format", "png16", "--out"])
        .arg(k15.join("disp_occ_1"))
        .args(flag)
        .output()
        .unwrap();
    [submit_middlebury, submit_kitti, predict]
}

/// `predict`, `submit` and `--overwrite` used to replace a dataset's files
/// that bear an output's name: MiddEval3's `disp0GTy.pfm`, KITTI 2012's
/// reflective-surface truth, KITTI 2015's right-view truth. Now a file
/// mbs did not write is refused whatever the flags.
#[test]
fn no_output_replaces_a_file_mbs_did_not_write() {
    let dir = tempfile::tempdir().unwrap();
    let middlebury = middeval3(dir.path());
    let k12 = kitti_2012(dir.path());
    let k15 = kitti_2015(dir.path());
    let before = tree(dir.path());
    let files = [
        "disp0GTy.pfm",
        "disp_refl_occ/000000_10.png",
        "disp_occ_1/000000_10.png",
    ];
    for flag in [&[][..], &["--overwrite"]] {
        let outputs = over_dataset_files(&middlebury, &k12, &k15, flag);
        for (output, file) in outputs.iter().zip(files) {
            refused(output, &[file, "mbs did not write it"]);
        }
    }
    unchanged(&before, &tree(dir.path()), "a dataset file changed");
}

/// mbs's own outputs are skipped on a second run and replaced with
/// `--overwrite`, as its record lists them.
#[test]
fn own_outputs_are_skipped_or_replaced_with_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    let k15 = kitti_2015(dir.path());
    let out = dir.path().join("pred");
    let predict = |extra: &[&str]| {
        let output = mbs_tool()
            .arg("predict")
            .arg("--kitti")
            .arg(&k15)
            .args(["--max-disparity", "32", "--out"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        succeeded(&output);
        text(&output)
    };
    predict(&[]);
    let second = predict(&[]);
    assert!(second.contains("0 done, 1 skipped"), "{second}");
    let third = predict(&["--overwrite"]);
    assert!(third.contains("1 done, 0 skipped"), "{third}");
    let record = std::fs::read_to_string(out.join(".mbs-written")).unwrap();
    assert_eq!(record, "000000_10.pfm\n");
    assert!(out.join(".mbs-lock").is_file());
    // Another source would leave the folder's predictions from two
    // matchers (the existing one skipped): refused, naming what differs,
    // and nothing changed; --overwrite recomputes them all with it.
    let before = std::fs::read(out.join("000000_10.pfm")).unwrap();
    let other = |extra: &[&str]| {
        mbs_tool()
            .args(["predict", "--kitti"])
            .arg(&k15)
            .args(["--max-disparity", "64", "--out"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap()
    };
    let refused = other(&[]);
    let said = text(&refused);
    assert!(!refused.status.success(), "{said}");
    assert!(
        said.contains("other settings") && said.contains("\"max_disparity\":32"),
        "{said}"
    );
    assert_eq!(std::fs::read(out.join("000000_10.pfm")).unwrap(), before);
    let replaced = other(&["--overwrite"]);
    succeeded(&replaced);
    assert!(
        text(&replaced).contains("1 done, 0 skipped"),
        "{}",
        text(&replaced)
    );
}

/// A second `extrapolate` into a folder with another inpainter would mix
/// two kinds of view (finished frames are skipped): refused, naming it.
#[test]
fn extrapolate_with_other_settings_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let k15 = kitti_2015(dir.path());
    let out = dir.path().join("sets");
    let run = |inpaint: &str| {
        mbs_tool()
            .args(["extrapolate", "--kitti"])
            .arg(&k15)
            .args(["--max-disparity", "32", "--inpaint", inpaint, "--out"])
            .arg(&out)
            .output()
            .unwrap()
    };
    succeeded(&run("background"));
    let manifest = std::fs::read(out.join("manifest.json")).unwrap();
    let other = run("isotropic");
    let said = text(&other);
    assert!(!other.status.success(), "{said}");
    assert!(
        said.contains("other settings") && said.contains("isotropic"),
        "{said}"
    );
    assert_eq!(std::fs::read(out.join("manifest.json")).unwrap(), manifest);
    succeeded(&run("background"));
}

/// `mbs-tool extrapolate ARGS`.
fn extrapolate(args: &[&str]) -> Output {
    mbs_tool().arg("extrapolate").args(args).output().unwrap()
}

/// The four `extrapolate` commands that would write over their inputs,
/// each with the file it would replace: `--disparity-dir D --out D`,
/// `--left-disparity D/disparity_2.pfm --out D`, `--kitti K
/// --left-disparity-dir K/disparity_2`, and a right view already named
/// `image_2.png` in `--out`.
fn extrapolations(
    root: &Path,
    (disparities, left_disparity): (&Path, &Path),
    (kitti, own): (&Path, &Path),
    named: &Path,
) -> Vec<(Output, &'static str)> {
    let pair = root.join("pair");
    let text = |path: &Path| path.to_str().unwrap().to_string();
    let (left, right) = (text(&pair.join("left.png")), text(&pair.join("right.png")));
    let (d, d2) = (text(disparities), text(left_disparity));
    let (k, own, named_dir) = (text(kitti), text(own), text(named));
    let named_right = text(&named.join("image_2.png"));
    let views = ["--left", left.as_str(), "--right", right.as_str()];
    vec![
        (
            extrapolate(&[&views[..], &["--disparity-dir", &d, "--out", &d]].concat()),
            "disparity_2.pfm",
        ),
        (
            extrapolate(&[&views[..], &["--left-disparity", &d2, "--out", &d]].concat()),
            "disparity_2.pfm",
        ),
        (
            extrapolate(&["--kitti", &k, "--left-disparity-dir", &own]),
            "disparity_2/000000_10.pfm",
        ),
        (
            extrapolate(&[
                "--left",
                &left,
                "--right",
                &named_right,
                "--max-disparity",
                "32",
                "--out",
                &named_dir,
            ]),
            "image_2.png",
        ),
    ]
}

/// `extrapolate` used to write its hole-filled disparities over the
/// disparity files it read, and the left view over a right view named
/// `image_2.png` in `--out`.
#[test]
fn extrapolate_never_writes_over_its_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let pair = dir.path().join("pair");
    teddy_view("im2.png", &pair.join("left.png"));
    teddy_view("im6.png", &pair.join("right.png"));
    let disparities = dir.path().join("disparities");
    std::fs::create_dir_all(&disparities).unwrap();
    let left_disparity = disparities.join("disparity_2.pfm");
    write_pfm_grey(&left_disparity, &teddy_truth(), Endian::Little).unwrap();
    let kitti = kitti_2015(dir.path());
    let own = kitti.join("disparity_2");
    std::fs::create_dir_all(&own).unwrap();
    write_pfm_grey(&own.join("000000_10.pfm"), &teddy_truth(), Endian::Little).unwrap();
    let named = dir.path().join("named");
    teddy_view("im6.png", &named.join("image_2.png"));
    let before = tree(dir.path());
    let cases = extrapolations(
        dir.path(),
        (&disparities, &left_disparity),
        (&kitti, &own),
        &named,
    );
    for (output, file) in &cases {
        refused(output, &[file, "refusing to replace an input"]);
    }
    unchanged(&before, &tree(dir.path()), "an input changed");
}

/// A small synthetic training set; its manifest.
fn training_set(root: &Path) -> String {
    common::synth(root)
}

/// `train` of the compact network into `out`, `steps` steps, with `extra`.
fn train_command(manifest: &str, out: &Path, steps: &str, extra: &[&str]) -> Command {
    let mut command = mbs_tool();
    command
        .args(["train", manifest, "--out"])
        .arg(out)
        .args(common::SMALL)
        .args(["--steps", steps, "--val-every", "1000"])
        .args(["--checkpoint-every", "2"])
        .args(extra);
    command
}

/// A child process killed when the test ends, passed or failed.
struct Killed(std::process::Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Two `train` processes into one folder used to both train; a
/// `--restart` meanwhile deleted the running run's checkpoints. Now the
/// second is refused at once, naming the first, and a `kill -9` of the
/// first frees the folder for the next run.
#[test]
fn one_process_per_run_folder_and_kill_releases_it() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = training_set(&dir.path().join("data"));
    let run = dir.path().join("run");
    let mut first = Killed(
        train_command(&manifest, &run, "100000", &[])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let checkpoints = run.join("checkpoints");
    let start = Instant::now();
    // The run checkpoints every 2 steps and prunes the older ones, so any
    // checkpoint will do (step 2's may be gone by the time it is looked for).
    let has_checkpoint = || {
        std::fs::read_dir(&checkpoints).is_ok_and(|entries| {
            entries
                .flatten()
                .any(|e| e.file_name().to_string_lossy().starts_with("step-"))
        })
    };
    while !has_checkpoint() {
        assert!(start.elapsed() < Duration::from_secs(300), "no checkpoint");
        assert!(first.0.try_wait().unwrap().is_none(), "the first run ended");
        std::thread::sleep(Duration::from_millis(100));
    }
    let pid = first.0.id().to_string();
    // Another run, a restart, and the same command again (a resume).
    for (steps, extra) in [("4", &[][..]), ("4", &["--restart"]), ("100000", &[])] {
        let output = within(train_command(&manifest, &run, steps, extra), 120);
        refused(&output, &["is in use by process", &pid, "(mbs-tool train)"]);
        // The first run prunes its older checkpoints as it goes, but
        // always keeps its newest: a restart would have removed them all.
        // (Listed, not read: a file read while the run prunes it could
        // vanish between the listing and the read.)
        assert!(has_checkpoint(), "the checkpoints went");
    }
    // SIGKILL, as `kill -9` sends: the run gets no chance to clean up.
    first.0.kill().unwrap();
    first.0.wait().unwrap();
    let output = within(train_command(&manifest, &run, "2", &["--restart"]), 300);
    succeeded(&output);
}

/// A held output folder refuses a batch command too (here `predict`,
/// while another process holds the folder's lock).
#[test]
fn a_held_output_folder_refuses_a_batch_command() {
    let dir = tempfile::tempdir().unwrap();
    let k15 = kitti_2015(dir.path());
    let out = dir.path().join("pred");
    std::fs::create_dir_all(&out).unwrap();
    let mut holder = Command::new("flock")
        .arg(out.join(".mbs-lock"))
        .args(["sleep", "120"])
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !out.join(".mbs-lock").exists() {
        assert!(start.elapsed() < Duration::from_secs(30));
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(200));
    let mut command = mbs_tool();
    command
        .arg("predict")
        .arg("--kitti")
        .arg(&k15)
        .arg("--out")
        .arg(&out);
    let output = within(command, 60);
    holder.kill().unwrap();
    holder.wait().unwrap();
    refused(&output, &["pred: is in use by"]);
    assert!(!out.join("000000_10.pfm").exists());
}

/// `predict --manifest` with a sample whose id names another sample's
/// file (not one of the pair's): refused, the file unchanged.
fn predict_over_another_samples_file(root: &Path, data: &Path, manifest: &str) {
    let text_manifest = std::fs::read_to_string(manifest).unwrap();
    let mut parsed: serde_json::Value = serde_json::from_str(&text_manifest).unwrap();
    let samples = parsed["samples"].as_array_mut().unwrap();
    let other = samples[0]["views"][3].as_str().unwrap().to_string();
    let stem = other.strip_suffix(".png").unwrap().to_string();
    samples[1]["id"] = stem.into();
    let edited = data.join("edited.json");
    std::fs::write(&edited, serde_json::to_vec(&parsed).unwrap()).unwrap();
    let before_predict = tree(root);
    let output = mbs_tool()
        .args(["predict", "--manifest"])
        .arg(&edited)
        .args(["--pair", "0:1", "--format", "png16", "--out"])
        .arg(data)
        .output()
        .unwrap();
    refused(&output, &[&other, "refusing to replace an input"]);
    unchanged(&before_predict, &tree(root), "an input changed");
    std::fs::remove_file(&edited).unwrap();
}

/// Outputs kept inside the run that predicts them are not its inputs: a
/// second `predict --checkpoint RUN --out RUN/pred` resumes, and
/// `--overwrite` replaces them.
fn predict_inside_the_run(k15: &Path, run: &Path) {
    let inside = run.join("pred");
    for extra in [&[][..], &[][..], &["--overwrite"]] {
        let output = mbs_tool()
            .arg("predict")
            .arg("--kitti")
            .arg(k15)
            .arg("--checkpoint")
            .arg(run)
            .arg("--out")
            .arg(&inside)
            .args(extra)
            .output()
            .unwrap();
        succeeded(&output);
    }
}

/// `benchmark --per-image` used to overwrite a file of the run it scores
/// (indexed as a folder); `train` indexed none of its inputs, so a
/// manifest named `config.json` in `--out` was replaced; `predict
/// --manifest` indexed a sample's two views only.
#[test]
fn inputs_are_indexed_down_to_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let manifest = training_set(&data);
    let run = dir.path().join("run");
    succeeded(&within(train_command(&manifest, &run, "2", &[]), 300));
    let k15 = kitti_2015(dir.path());
    let step = run.join("checkpoints/step-0000002");
    let before = tree(dir.path());
    for file in ["teacher.bpk", "state.json"] {
        let output = mbs_tool()
            .arg("benchmark")
            .arg("--kitti")
            .arg(&k15)
            .arg("--checkpoint")
            .arg(&run)
            .arg("--per-image")
            .arg(step.join(file))
            .output()
            .unwrap();
        refused(&output, &[file, "refusing to replace an input"]);
    }
    // The manifest as the run's config.json or train.jsonl.
    for name in ["config.json", "train.jsonl"] {
        let copy = data.join(name);
        std::fs::copy(&manifest, &copy).unwrap();
        let output = within(train_command(copy.to_str().unwrap(), &data, "2", &[]), 120);
        refused(&output, &[name, "refusing to replace an input"]);
        std::fs::remove_file(&copy).unwrap();
    }
    predict_over_another_samples_file(dir.path(), &data, &manifest);
    unchanged(&before, &tree(dir.path()), "an input changed");
    predict_inside_the_run(&k15, &run);
    // A run folder written before the record: its checkpoints say it is
    // mbs's, so it is taken again (here to start over).
    std::fs::remove_file(run.join(".mbs-written")).unwrap();
    let again = within(train_command(&manifest, &run, "2", &["--restart"]), 300);
    succeeded(&again);
}

/// `train --restart` used to delete the checkpoints and only then refuse
/// a FIFO `train.jsonl`, a folder named `config.json` or a `val.jsonl`
/// linked to `/dev/null`.
#[test]
fn restart_checks_everything_before_it_deletes() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = training_set(&dir.path().join("data"));
    let run = dir.path().join("run");
    succeeded(&within(train_command(&manifest, &run, "2", &[]), 300));
    let checkpoints = tree(&run.join("checkpoints"));
    assert!(!checkpoints.is_empty());
    type Spoil = fn(&Path);
    let cases: [(&str, Spoil, &str); 3] = [
        (
            "train.jsonl",
            |p| assert!(Command::new("mkfifo").arg(p).status().unwrap().success()),
            "FIFO",
        ),
        (
            "config.json",
            |p| std::fs::create_dir(p).unwrap(),
            "a folder",
        ),
        (
            "val.jsonl",
            |p| std::os::unix::fs::symlink("/dev/null", p).unwrap(),
            "character device",
        ),
    ];
    for (name, spoil, kind) in cases {
        let path = run.join(name);
        let saved = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        spoil(&path);
        let output = within(train_command(&manifest, &run, "2", &["--restart"]), 120);
        refused(&output, &[name, kind, "not a regular file"]);
        unchanged(&checkpoints, &tree(&run.join("checkpoints")), name);
        match std::fs::symlink_metadata(&path).unwrap().is_dir() {
            true => std::fs::remove_dir(&path).unwrap(),
            false => std::fs::remove_file(&path).unwrap(),
        }
        std::fs::write(&path, saved).unwrap();
    }
}
