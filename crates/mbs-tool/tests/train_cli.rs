//! `mbs-tool train` end to end: outputs, settings errors, Ctrl-C and
//! resumption, and the trained teacher through `eval` and `predict
//! --checkpoint`.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use common::{SMALL, lines, mbs_tool, run, synth, text};
use mbs_core::FloatImage;
use mbs_test_support::events::{EventValue, as_tensorboard_shows, read_events};
use mbs_test_support::files::complete_lines;
use serde_json::Value;

/// The arguments of a small training run on a synthetic set written into
/// `dir/data`: `train MANIFEST --out OUT --steps S --val-every V`, `extra`,
/// then the small settings.
fn small_run(dir: &Path, out: &Path, [steps, val_every]: [&str; 2], extra: &[&str]) -> Vec<String> {
    let manifest = synth(&dir.join("data"));
    let mut args: Vec<String> = vec![
        "train".into(),
        manifest,
        "--out".into(),
        out.display().to_string(),
        "--steps".into(),
        steps.into(),
        "--val-every".into(),
        val_every.into(),
    ];
    args.extend(extra.iter().chain(&SMALL).map(|a| a.to_string()));
    args
}

/// The size of a visual sheet: reference | teacher | student | GT | weight
/// map, 128x64 each under their captions, the disparity colour bar and the
/// weight map's key below.
const SHEET_SIZE: (u32, u32) = (664, 187);

/// A finished small training run and what the commands that read it share.
struct Trained<'a> {
    /// The test's temporary folder, which holds the run and the set.
    dir: &'a Path,
    /// The run's output folder.
    out: PathBuf,
    /// `out` as an argument.
    out_s: String,
    /// The synthetic set's manifest.
    manifest: String,
}

#[test]
fn trains_logs_draws_checkpoints_and_serves_the_teacher() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let owned = small_run(dir.path(), &out, ["6", "3"], &[]);
    let args: Vec<&str> = owned.iter().map(String::as_str).collect();
    let trained = Trained {
        dir: dir.path(),
        out,
        out_s: owned[3].clone(),
        manifest: owned[1].clone(),
    };
    let (train, val) = trains_and_logs(&args, &trained.out);
    tensorboard_shows_the_logs_and_the_sheets(&trained.out, &train);
    draws_sheets_and_checkpoints(&trained.out);
    the_best_teacher_is_kept_and_served(&trained, &val);
    a_finished_run_is_not_trained_again(&args, &trained.out);
    let validated_epe = val[2]["ALL"]["epe"].as_f64().unwrap();
    eval_scores_the_teacher_as_validated(&trained, &val[2]);
    let map = predict_writes_a_disparity_per_sample(&trained);
    let exported = export_writes_the_teacher(&trained);
    export_never_writes_over_the_checkpoint(&trained);
    export_refuses_special_files(&trained);
    let exported_s = exported.display().to_string();
    predict_with_the_export_gives_the_same_map(&trained, &exported_s, &map);
    extrapolate_takes_the_same_sources(&trained, &exported_s, &map);
    train_init_starts_from_the_teacher(&trained, &exported_s, validated_epe);
    weights_of_another_network_are_refused(&trained, &exported_s);
    weights_holding_a_nan_are_refused(&trained, &exported);
}

/// Trains with `args` and checks the settings, the training and validation
/// logs and the plots; returns the two logs.
fn trains_and_logs(args: &[&str], out: &Path) -> (Vec<Value>, Vec<Value>) {
    let output = run(args);
    assert!(output.status.success(), "{}", text(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("step 6: validation on"), "{stderr}");

    let config: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("config.json")).unwrap()).unwrap();
    assert_eq!(config["data"]["batch_size"], 2);
    assert_eq!(config["network"]["compact"]["features"], 8);
    assert_eq!(
        config["trainer"]["loss"]["omega"], 2.0,
        "paper default kept"
    );
    let train = lines(&out.join("train.jsonl"));
    assert_eq!(train.last().unwrap()["step"], 6);
    assert!(
        train
            .iter()
            .all(|l| l["loss"].as_f64().unwrap().is_finite())
    );
    // How much supervision the steps had: shares in [0, 1], an ordered range.
    for line in &train {
        let s = &line["supervision"];
        for share in ["student_mask", "teacher_mask", "outside"] {
            let v = s[share].as_f64().unwrap();
            assert!((0.0..=1.0).contains(&v), "{share} {v}");
        }
        let d = &s["disparity"];
        let (min, mean, max) = (d["min"].as_f64(), d["mean"].as_f64(), d["max"].as_f64());
        assert!(min <= mean && mean <= max, "{s}");
    }
    assert!(train.iter().all(|l| l.get("warning").is_none()));
    let val = lines(&out.join("val.jsonl"));
    let steps: Vec<u64> = val.iter().map(|l| l["step"].as_u64().unwrap()).collect();
    assert_eq!(steps, vec![0, 3, 6]);
    for region in ["ALL", "NOC", "OCC"] {
        assert!(val[2][region]["out3"].as_f64().is_some(), "{region}");
    }
    for plot in ["loss.png", "val.png"] {
        let image = image::open(out.join(plot)).unwrap();
        let size = (mbs_viz::chart::WIDTH, mbs_viz::chart::HEIGHT);
        assert_eq!((image.width(), image.height()), size, "{plot}");
    }
    (train, val)
}

/// TensorBoard's one event file holds the same numbers as the JSONL log
/// `train`, the validations, and the sheets.
fn tensorboard_shows_the_logs_and_the_sheets(out: &Path, train: &[Value]) {
    let event_files: Vec<_> = std::fs::read_dir(out.join("tensorboard"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(event_files.len(), 1, "{event_files:?}");
    let events = read_events(&event_files[0]).unwrap();
    let scalar = |tag: &str| -> Vec<(u64, f32)> {
        events
            .iter()
            .filter_map(|e| match &e.value {
                EventValue::Scalar(t, v) if t == tag => Some((e.step, *v)),
                _ => None,
            })
            .collect()
    };
    let losses = scalar("train/loss");
    assert_eq!(losses.len(), train.len());
    for ((step, value), line) in losses.iter().zip(train) {
        assert_eq!(*step, line["step"].as_u64().unwrap());
        let logged = line["loss"].as_f64().unwrap() as f32;
        assert!((value - logged).abs() <= 1e-6 * logged.abs().max(1.0));
    }
    for tag in [
        "train/lr",
        "train/momentum",
        "train/samples_per_s",
        "train/geometry",
    ] {
        assert_eq!(scalar(tag).len(), train.len(), "{tag}");
    }
    let out3: Vec<u64> = scalar("val/OCC/out3").iter().map(|(s, _)| *s).collect();
    assert_eq!(out3, vec![0, 3, 6]);
    let images = events
        .iter()
        .filter(|e| matches!(&e.value, EventValue::Image(_, size, _) if *size == SHEET_SIZE))
        .count();
    assert!(images >= 3, "{images} sheet images");
}

/// The last step's sheets are drawn and its checkpoint saved.
fn draws_sheets_and_checkpoints(out: &Path) {
    let sheets: Vec<_> = std::fs::read_dir(out.join("visuals/step-0000006"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert!(!sheets.is_empty());
    let sheet = image::open(&sheets[0]).unwrap();
    assert_eq!((sheet.width(), sheet.height()), SHEET_SIZE);
    assert!(out.join("checkpoints/step-0000006/teacher.bpk").is_file());
}

/// The best validation's teacher is kept in `checkpoints/best/`, a
/// checkpoint `export` (and `predict`, `eval`) take like any other.
fn the_best_teacher_is_kept_and_served(trained: &Trained, val: &[Value]) {
    let best = trained.out.join("checkpoints/best");
    let state: Value =
        serde_json::from_str(&std::fs::read_to_string(best.join("state.json")).unwrap()).unwrap();
    let out3 = |line: &Value| line["ALL"]["out3"].as_f64().unwrap();
    let lowest = val[1..].iter().map(out3).fold(f64::INFINITY, f64::min);
    let step = state["steps"].as_u64().unwrap();
    let scored = val.iter().find(|l| l["step"] == step).unwrap();
    assert_eq!(out3(scored), lowest, "{state}");
    for line in val {
        let range = &line["range"];
        assert!(
            range["predicted_p95"].as_f64().unwrap().is_finite(),
            "{line}"
        );
        assert!(range["truth_p95"].as_f64().unwrap() > 0.0, "{line}");
    }
    let exported = trained.dir.join("best.safetensors");
    let output = run(&[
        "export",
        &best.display().to_string(),
        "--out",
        &exported.display().to_string(),
    ]);
    assert!(output.status.success(), "{}", text(&output));
    assert!(exported.is_file());
}

/// The same command again finds the run complete, and logs nothing, so it
/// adds no event file.
fn a_finished_run_is_not_trained_again(args: &[&str], out: &Path) {
    let again = run(args);
    assert!(again.status.success(), "{}", text(&again));
    assert!(String::from_utf8_lossy(&again.stderr).contains("is complete"));
    let event_files_after = std::fs::read_dir(out.join("tensorboard")).unwrap().count();
    assert_eq!(event_files_after, 1);
}

/// `eval --checkpoint` scores the teacher on the held-out split under the
/// protocol validation used (`s3` by default, named in `val.jsonl`), and
/// gives every figure of the last validation of pair 0:1, `validated`, in
/// every region, within 1e-6.
fn eval_scores_the_teacher_as_validated(trained: &Trained, validated: &Value) {
    assert_eq!(validated["protocol"], "s3", "{validated}");
    let eval = run(&[
        "eval",
        "--checkpoint",
        &trained.out_s,
        "--manifest",
        &trained.manifest,
        "--pair",
        "0:1",
        "--split",
        "test",
        "--protocol",
        "s3",
        "--json",
    ]);
    assert!(eval.status.success(), "{}", text(&eval));
    let report: Value = serde_json::from_slice(&eval.stdout).unwrap();
    assert_eq!(report["protocol"], "s3");
    for region in ["ALL", "NOC", "OCC"] {
        for figure in ["pixels", "epe", "out1", "out2", "out3"] {
            let ours = validated[region][figure].as_f64();
            let theirs = report["score"][region][figure].as_f64();
            assert!(
                matches!((ours, theirs), (Some(a), Some(b)) if (a - b).abs() < 1e-6),
                "{region} {figure}: validation {ours:?} vs eval {theirs:?}"
            );
        }
    }
}

/// `predict --checkpoint` writes a finite disparity in range per sample;
/// returns the held-out sample's map.
fn predict_writes_a_disparity_per_sample(trained: &Trained) -> FloatImage {
    let pred = trained.dir.join("pred");
    let output = run(&[
        "predict",
        "--manifest",
        &trained.manifest,
        "--pair",
        "1:0",
        "--checkpoint",
        &trained.out_s,
        "--out",
        &pred.display().to_string(),
    ]);
    assert!(output.status.success(), "{}", text(&output));
    let map =
        mbs_core::formats::pfm::read_pfm_grey(&pred.join("Town10/ClearNoon/000000.pfm")).unwrap();
    assert_eq!(map.dimensions(), (128, 64));
    assert!(
        map.iter()
            .all(|d| d.is_finite() && (0.0..=32.0).contains(d))
    );
    map
}

/// `export` writes the teacher with the usual permissions; returns its path.
fn export_writes_the_teacher(trained: &Trained) -> PathBuf {
    let exported = trained.dir.join("teacher.safetensors");
    let output = run(&[
        "export",
        &trained.out_s,
        "--out",
        &exported.display().to_string(),
    ]);
    assert!(output.status.success(), "{}", text(&output));
    assert_usual_permissions(&exported);
    exported
}

/// `export` never writes over the checkpoint it reads: a name of another
/// extension becomes a .safetensors name beside it, and a link to a
/// checkpoint file (the same file under another name) is refused.
fn export_never_writes_over_the_checkpoint(trained: &Trained) {
    let out_s = &trained.out_s;
    let checkpoint = mbs_nets::checkpoint::TrainedNetworks::open(&trained.out).unwrap();
    let teacher_file = checkpoint.dir.join("teacher.bpk");
    let teacher_bytes = std::fs::read(&teacher_file).unwrap();
    let output = run(&["export", out_s, "--out", teacher_file.to_str().unwrap()]);
    assert!(output.status.success(), "{}", text(&output));
    assert!(
        text(&output).contains("is not a .safetensors name; writing"),
        "{}",
        text(&output)
    );
    assert_eq!(std::fs::read(&teacher_file).unwrap(), teacher_bytes);
    assert_usual_permissions(&checkpoint.dir.join("teacher.safetensors"));
    let linked = trained.dir.join("linked.safetensors");
    std::fs::hard_link(checkpoint.dir.join("state.json"), &linked).unwrap();
    let output = run(&["export", out_s, "--out", linked.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(
        text(&output).contains("would overwrite the checkpoint it exports")
            && text(&output).contains("state.json"),
        "{}",
        text(&output)
    );
    assert_eq!(std::fs::read(&teacher_file).unwrap(), teacher_bytes);
}

/// `export` does not write over a file that is not a regular file either
/// (issue 43): a device, a FIFO, a socket or a folder, under its own name
/// or as the .safetensors name export would add, is refused and left as it
/// was, and no file appears beside it.
fn export_refuses_special_files(trained: &Trained) {
    let specials = trained.dir.join("specials");
    std::fs::create_dir(&specials).unwrap();
    let listing = || {
        let mut names: Vec<_> = std::fs::read_dir(&specials)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        names.sort();
        names
    };
    for extension in ["safetensors", "bin"] {
        let files = mbs_test_support::special::special_files(&specials, extension);
        let before = listing();
        for file in &files {
            let identity = mbs_test_support::special::identity(&file.path);
            // The name itself, and (for .safetensors) the name without
            // its extension, which export would complete to it.
            let bare = file.path.with_extension("");
            let names = if extension == "safetensors" {
                vec![&file.path, &bare]
            } else {
                vec![&file.path]
            };
            for name in names {
                let output = run(&["export", &trained.out_s, "--out", name.to_str().unwrap()]);
                let report = text(&output);
                assert_eq!(output.status.code(), Some(1), "{report}");
                assert!(file.is_refused_in(&report), "{report}");
            }
            assert_eq!(mbs_test_support::special::identity(&file.path), identity);
        }
        assert_eq!(listing(), before, "export made a file beside a special one");
    }
}

/// The arguments that give `predict` or `extrapolate` the compact network
/// of the small runs with the weights file `weights`.
fn weights_source(weights: &str) -> [&str; 8] {
    [
        "--backbone",
        "compact",
        "--weights",
        weights,
        "--set",
        "network.max_disparity=32",
        "--set",
        "network.compact.features=8",
    ]
}

/// `predict --weights` with the exported teacher gives the checkpoint's
/// map, `map`.
fn predict_with_the_export_gives_the_same_map(
    trained: &Trained,
    exported_s: &str,
    map: &FloatImage,
) {
    let pred_weights = trained.dir.join("pred-weights");
    let pred_weights_s = pred_weights.display().to_string();
    let mut args = vec!["predict", "--manifest", &trained.manifest, "--pair", "1:0"];
    args.extend(weights_source(exported_s));
    args.extend(["--out", &pred_weights_s]);
    let output = run(&args);
    assert!(output.status.success(), "{}", text(&output));
    let same =
        mbs_core::formats::pfm::read_pfm_grey(&pred_weights.join("Town10/ClearNoon/000000.pfm"))
            .unwrap();
    assert_eq!(same.as_raw(), map.as_raw());
}

/// `extrapolate` takes the same sources: with the run's teacher, and with
/// the exported weights, the right view's disparity is predict's `map`.
fn extrapolate_takes_the_same_sources(trained: &Trained, exported_s: &str, map: &FloatImage) {
    let view = |k: usize| {
        trained
            .dir
            .join(format!("data/Town10/ClearNoon/000000/rgb_{k}.png"))
            .display()
            .to_string()
    };
    let (left, right) = (view(0), view(1));
    let weights = weights_source(exported_s);
    let sources: [&[&str]; 2] = [&["--checkpoint", &trained.out_s], &weights];
    for (i, source) in sources.iter().enumerate() {
        let extrapolated = trained.dir.join(format!("extrapolated-{i}"));
        let mut args = vec![
            "extrapolate",
            "--left",
            &left,
            "--right",
            &right,
            "--out",
            extrapolated.to_str().unwrap(),
        ];
        args.extend(source.iter());
        let output = run(&args);
        assert!(output.status.success(), "{}", text(&output));
        let right_disparity =
            mbs_core::formats::pfm::read_pfm_grey(&extrapolated.join("disparity_3.pfm")).unwrap();
        assert_eq!(right_disparity.as_raw(), map.as_raw(), "{source:?}");
    }
}

/// `train --init` (the run, or its export) starts a new run from the
/// teacher: its step-0 validation is the first run's last one,
/// `validated_epe`.
fn train_init_starts_from_the_teacher(trained: &Trained, exported_s: &str, validated_epe: f64) {
    for (name, init) in [("ft-run", trained.out_s.as_str()), ("ft-file", exported_s)] {
        let ft = trained.dir.join(name);
        let ft_s = ft.display().to_string();
        let mut args = vec![
            "train",
            &trained.manifest,
            "--out",
            &ft_s,
            "--init",
            init,
            "--steps",
            "2",
        ];
        args.extend(SMALL);
        let output = run(&args);
        assert!(output.status.success(), "{}", text(&output));
        assert!(
            String::from_utf8_lossy(&output.stderr).contains("starting from"),
            "{}",
            text(&output)
        );
        let first = &lines(&ft.join("val.jsonl"))[0];
        assert_eq!(first["step"], 0);
        let epe = first["ALL"]["epe"].as_f64().unwrap();
        assert!(
            (epe - validated_epe).abs() < 1e-6,
            "{name}: {epe} vs {validated_epe}"
        );
    }
}

/// Weights of another network are refused by `train --init`, naming the
/// file and the keys.
fn weights_of_another_network_are_refused(trained: &Trained, exported_s: &str) {
    let mismatch = trained.dir.join("mismatch");
    let mut args = vec![
        "train",
        &trained.manifest,
        "--out",
        mismatch.to_str().unwrap(),
        "--init",
        exported_s,
        "--backbone",
        "raft-stereo",
        "--steps",
        "2",
    ];
    args.extend(SMALL);
    let output = run(&args);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("teacher.safetensors: does not match the network"),
        "{stderr}"
    );
    assert!(stderr.contains("keys missing: cnet."), "{stderr}");
}

/// Weights holding a NaN (the `exported` teacher with one value changed)
/// are refused, naming the tensor, by every command that reads them;
/// nothing is predicted or trained.
fn weights_holding_a_nan_are_refused(trained: &Trained, exported: &Path) {
    let poisoned = trained.dir.join("poisoned.safetensors");
    let mut dict = mbs_nets::official::StateDict::read(exported).unwrap();
    let (key, tensor) = dict.tensors.iter_mut().nth(3).unwrap();
    let key = key.clone();
    tensor.values[0] = f32::NAN;
    dict.write_safetensors(&poisoned, &[]).unwrap();
    let poisoned_s = poisoned.display().to_string();
    let pred_poisoned = trained.dir.join("pred-poisoned");
    let mut args = vec!["predict", "--manifest", &trained.manifest, "--pair", "1:0"];
    args.extend(weights_source(&poisoned_s));
    args.extend(["--out", pred_poisoned.to_str().unwrap()]);
    let refused_init = trained.dir.join("poisoned-run");
    let mut init_args = vec![
        "train",
        &trained.manifest,
        "--out",
        refused_init.to_str().unwrap(),
        "--init",
        &poisoned_s,
        "--steps",
        "2",
    ];
    init_args.extend(SMALL);
    for args in [args, init_args] {
        let output = run(&args);
        assert_eq!(output.status.code(), Some(1), "{}", text(&output));
        let expected = format!("tensor {key} holds 1 non-finite values");
        assert!(text(&output).contains(&expected), "{}", text(&output));
    }
    assert!(!pred_poisoned.join("Town10/ClearNoon/000000.pfm").exists());
    assert!(!refused_init.join("checkpoints").exists());
}

#[test]
fn a_diverging_run_stops_with_an_error_and_keeps_its_last_good_weights() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let owned = small_run(dir.path(), &out, ["6", "1000"], &["--lr", "1e8"]);
    let args: Vec<&str> = owned.iter().map(String::as_str).collect();
    let output = run(&args);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("training diverged at step"), "{stderr}");
    assert!(
        stderr.contains("lower the learning rate (--lr)"),
        "{stderr}"
    );
    // The checkpoint left behind holds the steps before the divergence,
    // and loads: its weights are finite.
    let checkpoint = mbs_nets::checkpoint::TrainedNetworks::open(&out).unwrap();
    assert!(checkpoint.steps >= 1, "{}", checkpoint.steps);
    assert!(
        stderr.contains(&format!("diverged at step {}", checkpoint.steps + 1)),
        "{stderr}"
    );
    let device = burn::tensor::Device::flex();
    checkpoint.teacher(&device).unwrap();
    checkpoint.student(&device).unwrap();
}

#[test]
fn ctrl_c_saves_a_checkpoint_and_the_same_command_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let args = small_run(dir.path(), &out, ["400", "1000"], &["--set", "log_every=1"]);
    let state_file = ctrl_c_saves_a_checkpoint(&args, &out);
    let stopped = checkpoint_with_an_older_default(&state_file);
    changed_settings_are_refused(&args);
    let lines_before = the_same_command_resumes(&args, &out, stopped);
    tensorboard_shows_each_step_once(&args, &out, lines_before);
}

/// Starts the training command `args` with its stderr sent to `stderr`.
fn spawn_training(args: &[String], stderr: Stdio) -> Child {
    mbs_tool()
        .args(args)
        .stdout(Stdio::null())
        .stderr(stderr)
        .spawn()
        .unwrap()
}

/// Waits until the log of the run in `out` holds `count` complete lines
/// (while a run writes its log, only its complete lines are read), failing
/// with `message` after two minutes.
fn wait_for_logged_lines(out: &Path, count: usize, message: &str) {
    let start = Instant::now();
    while complete_lines(&out.join("train.jsonl")).len() < count {
        assert!(start.elapsed() < Duration::from_secs(120), "{message}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Runs `args`, waits for a few logged steps, then interrupts it as Ctrl-C
/// does: it fails, saying it saved a checkpoint; returns that checkpoint's
/// state file.
fn ctrl_c_saves_a_checkpoint(args: &[String], out: &Path) -> PathBuf {
    let child = spawn_training(args, Stdio::piped());
    wait_for_logged_lines(out, 3, "no training progress");
    let kill = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert!(stderr.contains("a checkpoint is saved"), "{stderr}");
    std::fs::read_dir(out.join("checkpoints"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| !p.to_string_lossy().ends_with(".partial"))
        .unwrap()
        .join("state.json")
}

/// Checks the step the checkpoint at `state_file` stopped at and returns
/// it, then rewrites the checkpoint as if it came from a version whose
/// default omega was 3.
fn checkpoint_with_an_older_default(state_file: &Path) -> u64 {
    let mut state: Value =
        serde_json::from_str(&std::fs::read_to_string(state_file).unwrap()).unwrap();
    let stopped = state["steps"].as_u64().unwrap();
    assert!((3..400).contains(&stopped), "{stopped}");
    state["config"]["trainer"]["loss"]["omega"] = 3.0.into();
    std::fs::write(state_file, state.to_string()).unwrap();
    stopped
}

/// The command `args` that also sets today's omega is refused, and so is
/// one with fewer total steps: the schedule would change.
fn changed_settings_are_refused(args: &[String]) {
    let mut explicit: Vec<&str> = args.iter().map(String::as_str).collect();
    explicit.extend(["--set", "trainer.loss.omega=2"]);
    let refused = run(&explicit);
    assert!(!refused.status.success());
    assert!(
        String::from_utf8_lossy(&refused.stderr).contains("trainer.loss.omega: 3.0 -> 2.0"),
        "{}",
        text(&refused)
    );
    let mut shorter: Vec<&str> = args.iter().map(String::as_str).collect();
    shorter[5] = "300";
    let refused = run(&shorter);
    assert!(!refused.status.success());
    assert!(
        String::from_utf8_lossy(&refused.stderr).contains("trainer.lr.total_steps: 400 -> 300"),
        "{}",
        text(&refused)
    );
}

/// The same command `args` resumes at the step it `stopped` at, with the
/// checkpoint's own omega, and logs the steps after it; it is killed (-9)
/// past its checkpoint. Returns how many lines the log then holds.
fn the_same_command_resumes(args: &[String], out: &Path, stopped: u64) -> usize {
    let mut resumed = spawn_training(args, Stdio::piped());
    wait_for_logged_lines(out, stopped as usize + 2, "no progress after resuming");
    resumed.kill().unwrap();
    let output = resumed.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    let out_s = &args[3];
    assert!(
        stderr.contains(&format!("resuming {out_s} at step {stopped} of 400")),
        "{stderr}"
    );
    assert!(
        stderr.contains("keeps its checkpoint's settings where today's defaults differ (checkpoint -> default): trainer.loss.omega: 3.0 -> 2.0"),
        "{stderr}"
    );
    let config: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("config.json")).unwrap()).unwrap();
    assert_eq!(config["trainer"]["loss"]["omega"], 3.0);
    let steps: Vec<u64> = lines(&out.join("train.jsonl"))
        .iter()
        .map(|l| l["step"].as_u64().unwrap())
        .collect();
    assert_eq!(
        steps[..stopped as usize + 1],
        (1..=stopped + 1).collect::<Vec<_>>()[..]
    );
    steps.len()
}

/// A third session of `args` logs again the steps the killed one logged
/// past its checkpoint (the log held `lines_before` lines), and
/// TensorBoard, which drops what earlier files logged from a session's
/// start on, shows each step once.
fn tensorboard_shows_each_step_once(args: &[String], out: &Path, lines_before: usize) {
    let mut third = spawn_training(args, Stdio::null());
    wait_for_logged_lines(out, lines_before + 3, "no progress");
    third.kill().unwrap();
    third.wait().unwrap();
    let mut files: Vec<_> = std::fs::read_dir(out.join("tensorboard"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert_eq!(files.len(), 3, "{files:?}");
    let per_file: Vec<_> = files.iter().map(|f| read_events(f).unwrap()).collect();
    let logged: Vec<u64> = per_file
        .iter()
        .flatten()
        .filter_map(|e| {
            matches!(&e.value, EventValue::Scalar(t, _) if t == "train/loss").then_some(e.step)
        })
        .collect();
    assert!(
        logged.len()
            > logged
                .iter()
                .collect::<std::collections::BTreeSet<_>>()
                .len(),
        "the killed session logged no step twice, so this checks nothing: {logged:?}"
    );
    let shown: Vec<u64> = as_tensorboard_shows(per_file)
        .into_iter()
        .filter_map(|e| {
            matches!(&e.value, EventValue::Scalar(t, _) if t == "train/loss").then_some(e.step)
        })
        .collect();
    assert_eq!(shown, (1..=shown.len() as u64).collect::<Vec<_>>());
}

#[test]
fn bad_settings_and_inputs_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run").display().to_string();
    let missing = dir.path().join("nope.json").display().to_string();
    let output = run(&["train", &missing, "--out", &out]);
    assert!(!output.status.success());
    // Named once (the reader's message is not prefixed with the path again),
    // and nothing is written.
    assert_eq!(
        String::from_utf8_lossy(&output.stderr)
            .matches(&missing)
            .count(),
        1,
        "{}",
        text(&output)
    );
    assert!(!std::path::Path::new(&out).exists());

    let output = run(&["train", "--print-config", "--set", "trainer.loss.omgea=3"]);
    assert!(!output.status.success());
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("unknown key `trainer.loss.omgea`"),
        "{}",
        text(&output)
    );

    // --print-config gives every setting, with the flags applied.
    let output = run(&[
        "train",
        "--print-config",
        "--steps",
        "77",
        "--crop",
        "256x512",
    ]);
    assert!(output.status.success(), "{}", text(&output));
    let config: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(config["trainer"]["lr"]["total_steps"], 77);
    assert_eq!(config["data"]["crop_height"], 256);
    assert_eq!(config["trainer"]["lr"]["max_lr"], 2e-4);

    let output = run(&["train", "--print-config", "--crop", "256by512"]);
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("HEIGHTxWIDTH"));

    // A crop larger than the images is refused with the sample's size.
    let manifest = synth(&dir.path().join("data"));
    let output = run(&["train", &manifest, "--out", &out, "--crop", "384x512"]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("is 64x128") && stderr.contains("smaller than the 384x512 crop"),
        "{stderr}"
    );
}

#[test]
fn vanished_supervision_is_warned_about_while_training() {
    // tau = 1e-6: no photometric error passes the threshold, so both masks
    // are empty from the first step, as in a collapsed run.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let tiny_tau = ["--set", "trainer.loss.tau=0.000001"];
    let owned = small_run(dir.path(), &out, ["12", "12"], &tiny_tau);
    let output = run(&owned.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(output.status.success(), "{}", text(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("warning: step 10: supervision has nearly vanished for 10 steps"),
        "{stderr}"
    );
    assert!(stderr.contains("student mask 0.0%"), "{stderr}");
    let train = lines(&out.join("train.jsonl"));
    let warnings: Vec<&str> = train.iter().filter_map(|l| l["warning"].as_str()).collect();
    assert_eq!(warnings.len(), 1, "{train:?}");
    assert!(warnings[0].starts_with("step 10: supervision has nearly vanished"));
    let share = train[0]["supervision"]["student_mask"].as_f64().unwrap();
    assert!(share < 1e-3, "{share}");
}

/// `path` has the permissions of a file this process creates (the umask
/// applied to 0666), like every other output.
fn assert_usual_permissions(path: &Path) {
    use std::os::unix::fs::PermissionsExt;
    let probe = path.with_extension("probe");
    std::fs::write(&probe, b"").unwrap();
    let usual = std::fs::metadata(&probe).unwrap().permissions().mode() & 0o777;
    std::fs::remove_file(&probe).unwrap();
    let mode = std::fs::metadata(path).unwrap().permissions().mode() & 0o777;
    assert_eq!(
        mode,
        usual,
        "{}: {mode:o}, expected {usual:o}",
        path.display()
    );
}

#[test]
fn a_training_image_with_corrupt_pixels_is_skipped_and_listed() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let owned = small_run(dir.path(), &out, ["6", "1000"], &["--set", "log_every=1"]);
    let args: Vec<&str> = owned.iter().map(String::as_str).collect();
    let manifest: Value =
        serde_json::from_str(&std::fs::read_to_string(&owned[1]).unwrap()).unwrap();
    let sample = manifest["samples"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["split"] == "train")
        .unwrap();
    let root = Path::new(&owned[1]).parent().unwrap();
    let corrupt = root.join(sample["views"][2].as_str().unwrap());
    // The header and the trailer stay whole; the compressed pixels do not.
    let mut bytes = std::fs::read(&corrupt).unwrap();
    let middle = bytes.len() / 2;
    for byte in &mut bytes[middle..middle + 32] {
        *byte ^= 0x5a;
    }
    std::fs::write(&corrupt, &bytes).unwrap();
    let validated = run(&["validate", &owned[1]]);
    assert!(validated.status.success(), "{}", text(&validated));

    let output = run(&args);
    assert!(output.status.success(), "{}", text(&output));
    let name = corrupt.display().to_string();
    assert!(
        text(&output).contains("skipping an unusable image") && text(&output).contains(&name),
        "{}",
        text(&output)
    );
    let logged = lines(&out.join("train.jsonl"));
    let listed: Vec<&Value> = logged
        .iter()
        .filter(|l| l.get("skipped").is_some())
        .collect();
    assert_eq!(listed.len(), 1, "listed once: {logged:?}");
    assert!(listed[0]["skipped"][0].as_str().unwrap().contains(&name));
    assert_eq!(logged.last().unwrap()["skipped_images"], 1);
}
