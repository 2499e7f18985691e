//! `--device` end to end: training, evaluation and data-parallel training
//! on Vulkan against the CPU, and the errors of devices that cannot be
//! used. Vulkan runs on every test run through Mesa's lavapipe, a CPU
//! Vulkan driver (`apt-get install mesa-vulkan-drivers`; `tools/test.sh`
//! installs it), so every kernel of the compact network, the losses, warps
//! and SSIM runs on burn's wgpu backend here (RAFT-Stereo's and
//! IGEV-Stereo's are compared in `mbs_nets`' Vulkan tests);
//! without a Vulkan driver these tests fail, they never skip.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;

use common::{SMALL, lines, mbs_tool, run, synth, text};
use serde_json::Value;

/// The `train` arguments: the small settings, those of `extra` in place of
/// the small ones they name, a fixed seed and a log line per step.
fn train_args<'a>(
    manifest: &'a str,
    out: &'a str,
    device: &'a str,
    extra: &[&'a str],
) -> Vec<&'a str> {
    let mut args = vec![
        "train", manifest, "--out", out, "--device", device, "--seed", "5",
    ];
    args.extend(["--set", "log_every=1"]);
    for pair in SMALL.chunks(2) {
        if pair[0] == "--set" || !extra.contains(&pair[0]) {
            args.extend(pair);
        }
    }
    args.extend(extra);
    args
}

/// What a training run logged.
#[derive(Debug)]
struct Logged {
    /// The loss of each step.
    losses: Vec<f64>,
    /// The gradient norm of each step.
    grad_norms: Vec<f64>,
    /// The last validation's EPE.
    epe: f64,
}

/// Trains with [`train_args`] and reads the logs.
fn train(manifest: &str, out: &Path, device: &str, extra: &[&str]) -> Logged {
    let out_s = out.display().to_string();
    let output = run(&train_args(manifest, &out_s, device, extra));
    assert!(output.status.success(), "{device}: {}", text(&output));
    let log = lines(&out.join("train.jsonl"));
    let column = |key: &str| log.iter().map(|l| l[key].as_f64().unwrap()).collect();
    Logged {
        losses: column("loss"),
        grad_norms: column("grad_norm"),
        epe: lines(&out.join("val.jsonl")).last().unwrap()["ALL"]["epe"]
            .as_f64()
            .unwrap(),
    }
}

/// Each value within `tolerance` of the CPU's, relative.
fn assert_losses_close(got: &[f64], want: &[f64], tolerance: f64, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: {got:?} vs {want:?}");
    for (step, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= tolerance * w.abs(),
            "{what}: step {step}: {g} vs {w} on the CPU (tolerance {tolerance} relative)\n{got:?}\n{want:?}"
        );
    }
}

/// Pooled EPE of `eval --checkpoint RUN --device DEVICE` on the held-out town.
fn eval_epe(run_dir: &Path, manifest: &str, device: &str) -> f64 {
    let run_s = run_dir.display().to_string();
    let output = run(&[
        "eval",
        "--checkpoint",
        &run_s,
        "--manifest",
        manifest,
        "--split",
        "test",
        "--device",
        device,
        "--json",
    ]);
    assert!(output.status.success(), "{device}: {}", text(&output));
    let report: Value = serde_json::from_slice(&output.stdout).unwrap();
    report["pooled"]["ALL"]["epe"].as_f64().unwrap()
}

#[test]
fn compact_network_trains_and_evaluates_on_vulkan_as_on_the_cpu() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = synth(&dir.path().join("data"));
    let steps = ["--steps", "4", "--val-every", "4"];
    let cpu = train(&manifest, &dir.path().join("cpu"), "cpu", &steps);
    let vulkan = train(&manifest, &dir.path().join("vk"), "vulkan", &steps);
    println!("compact: cpu {cpu:?}; vulkan {vulkan:?}");
    // Same seed, same weights (drawn on the CPU), same batches: 3e-4 apart
    // after 4 steps when written.
    assert_losses_close(&vulkan.losses, &cpu.losses, 1e-3, "compact losses");
    assert_losses_close(
        &vulkan.grad_norms,
        &cpu.grad_norms,
        1e-2,
        "compact gradient norms",
    );
    assert!(
        (vulkan.epe - cpu.epe).abs() <= 1e-2 * cpu.epe,
        "{vulkan:?} {cpu:?}"
    );
    // The Vulkan run's checkpoint evaluates the same on either device.
    let on_cpu = eval_epe(&dir.path().join("vk"), &manifest, "cpu");
    let on_vulkan = eval_epe(&dir.path().join("vk"), &manifest, "vulkan");
    assert!(
        (on_vulkan - on_cpu).abs() <= 1e-3 * on_cpu,
        "{on_vulkan} vs {on_cpu}"
    );
}

#[test]
fn data_parallel_training_across_devices_resumes_on_one() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = synth(&dir.path().join("data"));
    let steps = [
        "--steps",
        "4",
        "--val-every",
        "4",
        "--checkpoint-every",
        "2",
        "--batch-size",
        "4",
    ];
    // The same shares on two copies of the CPU and on the CPU and Vulkan.
    let cpus = train(&manifest, &dir.path().join("cpus"), "cpu,cpu", &steps);
    let mixed_out = dir.path().join("mixed");
    let mixed = train(&manifest, &mixed_out, "cpu,vulkan", &steps);
    println!("data parallel: cpu,cpu {cpus:?}; cpu,vulkan {mixed:?}");
    assert_losses_close(
        &mixed.losses,
        &cpus.losses,
        1e-3,
        "cpu,vulkan against cpu,cpu",
    );
    // A checkpoint of the two-device run resumes on one device.
    std::fs::remove_dir_all(mixed_out.join("checkpoints/step-0000004")).unwrap();
    let out_s = mixed_out.display().to_string();
    let output = run(&train_args(&manifest, &out_s, "vulkan", &steps));
    assert!(output.status.success(), "{}", text(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("at step 2 of 4"), "{stderr}");
    let resumed = lines(&mixed_out.join("train.jsonl"));
    let steps: Vec<u64> = resumed
        .iter()
        .map(|l| l["step"].as_u64().unwrap())
        .collect();
    assert_eq!(steps, [1, 2, 3, 4]);
}

#[test]
fn unusable_devices_are_one_clear_error_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("manifest.json");
    std::fs::write(&manifest, "{}").unwrap();
    let manifest = manifest.display().to_string();
    let out = dir.path().join("run");
    let out_s = out.display().to_string();
    // A device that cannot be opened is a run-time error (exit 1, one
    // line); a name that is no device is a usage error (exit 2), as for
    // every flag.
    let cases = [
        // No Vulkan driver: the loader finds no driver manifest.
        ("vulkan", "no usable Vulkan device", true, 1),
        ("cpu,vulkan:3", "no usable Vulkan device", true, 1),
        ("cuda", "--features cuda", false, 1),
        ("tpu", "unknown device", false, 2),
    ];
    for (device, expected, hide_drivers, status) in cases {
        let mut command = mbs_tool();
        command.args(["train", &manifest, "--out", &out_s, "--device", device]);
        if hide_drivers {
            command
                .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
                .env("VK_DRIVER_FILES", "/nonexistent/icd.json");
        }
        let output = command.output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(
            output.status.code(),
            Some(status),
            "{device}: {}",
            text(&output)
        );
        let first = stderr.lines().next().unwrap_or_default();
        assert!(first.contains(expected), "{device}: {stderr}");
        assert!(first.contains("device `"), "{device}: {stderr}");
        assert!(!stderr.contains("panicked"), "{device}: {stderr}");
        if status == 1 {
            assert_eq!(stderr.trim().lines().count(), 1, "{device}: {stderr}");
        }
        assert!(!out.exists(), "{device}: --out was created");
    }
}

/// `--precision f16` (mixed precision) on Vulkan: the same 4 steps as on
/// the CPU in f16 and close to the f32 run's (from a loss scale the compact
/// network's gradients fit, so no step is skipped), with the scale in
/// `train.jsonl` and in the checkpoint; bf16, which lavapipe cannot compute
/// in, is one clear error before anything is written.
#[test]
fn mixed_precision_trains_on_vulkan_as_on_the_cpu() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = synth(&dir.path().join("data"));
    let steps = ["--steps", "4", "--val-every", "4"];
    let f16 = |device: &str| {
        let out = dir.path().join(format!("f16-{device}"));
        let f16 = [
            "--precision",
            "f16",
            "--set",
            "trainer.initial_loss_scale=32",
        ];
        let logged = train(&manifest, &out, device, &[&steps[..], &f16].concat());
        let scales: Vec<f64> = lines(&out.join("train.jsonl"))
            .iter()
            .map(|l| l["loss_scale"].as_f64().unwrap())
            .collect();
        assert_eq!(scales, [32.0; 4], "{device}");
        // The checkpoint keeps the scale for a resumed run.
        let state: Value = serde_json::from_str(
            &std::fs::read_to_string(out.join("checkpoints/step-0000004/state.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(
            state["loss_scale"],
            serde_json::json!({"scale": 32.0, "good_steps": 4}),
            "{device}"
        );
        logged
    };
    let exact = train(&manifest, &dir.path().join("f32"), "cpu", &steps);
    let cpu = f16("cpu");
    let vulkan = f16("vulkan");
    println!("f16: cpu {cpu:?}; vulkan {vulkan:?}; f32 {exact:?}");
    assert_losses_close(&vulkan.losses, &cpu.losses, 1e-2, "f16 on Vulkan");
    assert_losses_close(&cpu.losses, &exact.losses, 0.1, "f16 against f32");

    let out = dir.path().join("bf16");
    let out_s = out.display().to_string();
    let mut args = train_args(&manifest, &out_s, "vulkan", &steps);
    args.extend(["--precision", "bf16"]);
    let output = run(&args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(
        stderr.contains("device `vulkan`: it cannot compute in bf16"),
        "{stderr}"
    );
    assert!(!out.exists(), "--out was created");
}

/// Vulkan drivers print to stderr while a device opens (Mesa's lavapipe,
/// without `XDG_RUNTIME_DIR`: "error: XDG_RUNTIME_DIR is invalid or not
/// set in the environment.", four times). A CPU run, fresh, resumed or
/// already complete, opens no GPU at all; a Vulkan run passes on what the
/// driver printed once a line, labelled as the driver's, so no line of
/// stderr looks like an mbs error.
#[test]
fn a_cpu_run_probes_no_gpu_and_driver_output_is_labelled() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = synth(&dir.path().join("data"));
    let steps = [
        "--steps",
        "2",
        "--val-every",
        "2",
        "--checkpoint-every",
        "1",
    ];
    let train_without_a_desktop = |out: &Path, device: &str| {
        let out_s = out.display().to_string();
        let output = mbs_tool()
            .args(train_args(&manifest, &out_s, device, &steps))
            .env_remove("XDG_RUNTIME_DIR")
            .output()
            .unwrap();
        assert!(output.status.success(), "{device}: {}", text(&output));
        String::from_utf8_lossy(&output.stderr).into_owned()
    };
    let cpu = dir.path().join("cpu");
    let fresh = train_without_a_desktop(&cpu, "cpu");
    std::fs::remove_dir_all(cpu.join("checkpoints/step-0000002")).unwrap();
    let resumed = train_without_a_desktop(&cpu, "cpu");
    assert!(resumed.contains("at step 1 of 2"), "{resumed}");
    let complete = train_without_a_desktop(&cpu, "cpu");
    assert!(
        complete.contains("is complete (2 of 2 steps)"),
        "{complete}"
    );
    for stderr in [fresh, resumed, complete] {
        assert!(!stderr.contains("XDG_RUNTIME_DIR"), "{stderr}");
        assert!(!stderr.contains("Vulkan"), "{stderr}");
    }
    let vulkan = train_without_a_desktop(&dir.path().join("vulkan"), "vulkan");
    for line in vulkan.lines() {
        assert!(!line.starts_with("error"), "{vulkan}");
        if line.contains("XDG_RUNTIME_DIR") {
            assert!(
                line.starts_with("note: the Vulkan driver printed: "),
                "{vulkan}"
            );
        }
    }
    let labelled = vulkan.matches("XDG_RUNTIME_DIR").count();
    assert!(labelled <= 1, "{vulkan}");
}
