//! Times the S3 training step ([`S3Trainer::step`]) of the compact network,
//! RAFT-Stereo or IGEV-Stereo (`--backbone raft-stereo|igev`) on the CPU
//! (`flex` backend), or on `--device cuda|vulkan[:N]` in a build with that
//! feature (`--features cuda`: each step reads its loss back, so its time
//! includes the device's work); called by `tools/bench/train_step_vs_torch.py` and
//! `tools/bench/official_step_vs_torch.py`. Run in release:
//!
//! ```text
//! RAYON_NUM_THREADS=2 cargo run --release -p mbs-train --example step_time -- \
//!     --batch 2 --height 256 --width 512 --max-disparity 128 --steps 5 --warmup 2
//! ```
//!
//! The compact network has the default 16 feature and 32 hidden channels;
//! RAFT-Stereo and IGEV-Stereo the official defaults unless `--hidden-dim`,
//! `--gru-levels`, `--train-iters`, `--test-iters` (both) or
//! `--n-downsample` (RAFT-Stereo) say otherwise (full size at the paper's
//! 384x512 crop: `--backbone igev --height 384 --width 512 --steps 1
//! --warmup 0`); `--precision bf16|f16` computes the networks in mixed
//! precision (`trainer.precision`); the loss has the paper's defaults. The batch is random images (fixed seed) with
//! the student's targets alternately right and left of the reference (so
//! every other item goes through the mirroring), teacher targets on the
//! right and baseline ratios alternately 1 and 1/2, as the ignored test
//! `step_time_at_256x512`. The student's input is the clean pair (no
//! augmentation: it is not part of the step). After `--warmup` steps, times
//! `--steps` steps and prints one JSON line:
//!
//! ```text
//! {"framework":"burn","device":"cpu","backbone":"compact","batch":2,"height":256,"width":512,"max_disparity":128,"ms_per_step":...,"peak_rss_mib":...}
//! ```
//!
//! (plus the step counts, the thread count and the last loss). `peak_rss_mib`
//! is `VmHWM` of `/proc/self/status` (`null` where there is none).
//!
//! `--breakdown` adds `breakdown_ms`: the same step taken apart with the
//! crate's public pieces and timed phase by phase (teacher forward, student
//! forward, loss, backward, clipping + Adam + EMA), averaged over `--steps`
//! more steps after the timed ones. The flex backend runs eagerly, so each
//! phase's time is its own.

/// The allocator `mbs-tool` uses, so the timings are what users get.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::fmt::Write as _;
use std::time::Instant;

use burn::module::Module;
use burn::optim::{GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Distribution, Tensor};
use mbs_core::geometry::Side;
use mbs_nets::{
    BackboneKind, CostVolumeNetConfig, IgevStereoConfig, NetworkConfig, RaftStereoConfig,
    StereoNetwork, predict,
};
use mbs_train::clip::clip_global_norm;
use mbs_train::ema::ema_update;
use mbs_train::precision::Precision;
use mbs_train::schedule::OneCycleConfig;
use mbs_train::{LossConfig, LossInputs, S3Loss, S3Trainer, StepBatch, TrainerConfig};

type BoxError = Box<dyn std::error::Error>;

const USAGE: &str = "usage: step_time [--backbone compact|raft-stereo|igev] [--batch B] [--height H] \
[--width W] [--max-disparity D] [--steps N] [--warmup K] [--features F] [--hidden C] [--seed S] \
[--breakdown] [--precision f32|bf16|f16] [--device cpu|cuda[:N]|vulkan[:N]] [--hidden-dim C] [--gru-levels L] [--n-downsample N] [--train-iters I] [--test-iters I]
defaults: --backbone compact --batch 2 --height 256 --width 512 --max-disparity 128 --steps 5 \
--warmup 2 --features 16 --hidden 32 --seed 42 --precision f32 --device cpu; the official networks' defaults";

/// What the command line sets.
#[derive(Debug)]
struct Args {
    backbone: BackboneKind,
    raft: RaftStereoConfig,
    igev: IgevStereoConfig,
    batch: usize,
    height: usize,
    width: usize,
    max_disparity: usize,
    steps: usize,
    warmup: usize,
    features: usize,
    hidden: usize,
    seed: u64,
    breakdown: bool,
    precision: Precision,
    device: String,
}

impl Args {
    /// Parses `--name value` pairs (and the `--breakdown` switch).
    fn parse(mut args: impl Iterator<Item = String>) -> Result<Self, String> {
        let mut out = Args::defaults();
        while let Some(flag) = args.next() {
            out.set(&flag, &mut args)?;
        }
        for (name, value) in [
            ("--batch", out.batch),
            ("--height", out.height),
            ("--width", out.width),
            ("--steps", out.steps),
        ] {
            if value == 0 {
                return Err(format!("{name} must be at least 1"));
            }
        }
        Ok(out)
    }

    /// The settings without flags, as [`USAGE`] lists them.
    fn defaults() -> Self {
        Args {
            backbone: BackboneKind::Compact,
            raft: RaftStereoConfig::new(),
            igev: IgevStereoConfig::new(),
            batch: 2,
            height: 256,
            width: 512,
            max_disparity: 128,
            steps: 5,
            warmup: 2,
            features: 16,
            hidden: 32,
            seed: 42,
            breakdown: false,
            precision: Precision::F32,
            device: "cpu".into(),
        }
    }

    /// Applies `flag`, taking its value from `args` where it has one;
    /// `--help` gives [`USAGE`] as the error.
    fn set(&mut self, flag: &str, args: &mut impl Iterator<Item = String>) -> Result<(), String> {
        match flag {
            "--help" | "-h" => return Err(USAGE.into()),
            "--breakdown" => self.breakdown = true,
            "--precision" => {
                let value = value_of(flag, args)?;
                self.precision = serde_json::from_value(serde_json::Value::String(value.clone()))
                    .map_err(|_| {
                    format!("--precision expects f32, bf16 or f16, got '{value}'")
                })?;
            }
            "--device" => self.device = value_of(flag, args)?,
            "--backbone" => {
                self.backbone = value_of(flag, args)?.parse().map_err(|e| format!("{e}"))?;
            }
            "--seed" => self.seed = integer_of(flag, args)?,
            _ => {
                if let Some((raft, igev)) = self.official_slots(flag) {
                    *raft = integer_of(flag, args)?;
                    *igev = *raft;
                } else {
                    let slot = self.slot(flag)?;
                    *slot = integer_of(flag, args)?;
                }
            }
        }
        Ok(())
    }

    /// The RAFT-Stereo and IGEV-Stereo settings that `flag` sets in both
    /// networks, if it is one of those flags.
    fn official_slots(&mut self, flag: &str) -> Option<(&mut usize, &mut usize)> {
        match flag {
            "--hidden-dim" => Some((&mut self.raft.hidden_dim, &mut self.igev.hidden_dim)),
            "--gru-levels" => Some((&mut self.raft.gru_levels, &mut self.igev.gru_levels)),
            "--train-iters" => Some((&mut self.raft.train_iters, &mut self.igev.train_iters)),
            "--test-iters" => Some((&mut self.raft.test_iters, &mut self.igev.test_iters)),
            _ => None,
        }
    }

    /// The integer setting that `flag` sets, or an error naming an unknown
    /// flag.
    fn slot(&mut self, flag: &str) -> Result<&mut usize, String> {
        Ok(match flag {
            "--batch" => &mut self.batch,
            "--height" => &mut self.height,
            "--width" => &mut self.width,
            "--max-disparity" => &mut self.max_disparity,
            "--steps" => &mut self.steps,
            "--warmup" => &mut self.warmup,
            "--features" => &mut self.features,
            "--hidden" => &mut self.hidden,
            "--n-downsample" => &mut self.raft.n_downsample,
            other => return Err(format!("unknown argument '{other}'\n{USAGE}")),
        })
    }

    /// Refuses the settings `--breakdown` cannot take apart: it times f32
    /// steps of the compact network on the CPU only.
    fn check_breakdown(&self) -> Result<(), BoxError> {
        if self.breakdown && self.backbone != BackboneKind::Compact {
            return Err("--breakdown times the compact network only".into());
        }
        if self.breakdown && self.device != "cpu" {
            return Err("--breakdown times CPU steps only".into());
        }
        if self.breakdown && self.precision != Precision::F32 {
            return Err("--breakdown times f32 steps only".into());
        }
        Ok(())
    }

    /// The network the settings describe.
    fn network(&self) -> NetworkConfig {
        NetworkConfig::new()
            .with_backbone(self.backbone)
            .with_max_disparity(self.max_disparity)
            .with_compact(
                CostVolumeNetConfig::new()
                    .with_features(self.features)
                    .with_hidden(self.hidden),
            )
            .with_raft_stereo(self.raft.clone())
            .with_igev(self.igev.clone())
    }
}

/// The value after `flag`, taken from `args`.
fn value_of(flag: &str, args: &mut impl Iterator<Item = String>) -> Result<String, String> {
    args.next().ok_or_else(|| format!("{flag} needs a value"))
}

/// The integer after `flag`, taken from `args`.
fn integer_of<T: std::str::FromStr>(
    flag: &str,
    args: &mut impl Iterator<Item = String>,
) -> Result<T, String> {
    let value = value_of(flag, args)?;
    value
        .parse()
        .map_err(|_| format!("{flag} expects an integer >= 0, got '{value}'"))
}

/// Peak resident set size (`VmHWM`) in MiB, on Linux.
fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|line| line.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// The benchmark batch: random clean images, the student's input un-augmented.
fn batch(args: &Args, device: &Device) -> StepBatch {
    let image = || {
        Tensor::<4>::random(
            [args.batch, 3, args.height, args.width],
            Distribution::Default,
            device,
        )
    };
    let reference = image();
    let student_target = image();
    let teacher_target = image();
    let even = |i: &usize| i.is_multiple_of(2);
    StepBatch {
        augmented_reference: reference.clone(),
        augmented_target: student_target.clone(),
        reference,
        student_target,
        teacher_target,
        student_sides: (0..args.batch)
            .map(|i| if even(&i) { Side::Right } else { Side::Left })
            .collect(),
        teacher_sides: vec![Side::Right; args.batch],
        ratios: (0..args.batch)
            .map(|i| if even(&i) { 1.0 } else { 0.5 })
            .collect(),
    }
}

/// Milliseconds since `start`.
fn millis(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// The phases [`breakdown`] times, in the order a step runs them.
const PHASES: [&str; 5] = [
    "teacher_forward",
    "student_forward",
    "loss",
    "backward",
    "clip_adam_ema",
];

/// The step taken apart into its phases, as `S3Trainer::step` runs them;
/// returns the mean milliseconds of each phase over `steps` steps.
fn breakdown(
    student: StereoNetwork,
    config: &TrainerConfig,
    batch: &StepBatch,
    steps: usize,
) -> Result<Vec<(&'static str, f64)>, BoxError> {
    let mut student = student;
    let mut teacher = student.valid();
    let loss = S3Loss::new(config.loss.clone())?;
    let schedule = config.lr.init()?;
    let mut optimizer: ModuleOptimizer = config.optimizer.init();
    let mut totals = [0.0f64; 5];
    for step in 0..steps {
        let total = timed_loss(&teacher, &student, &loss, batch.clone(), &mut totals)?;
        let start = Instant::now();
        let mut grads = GradientsParams::from_grads(total.backward(), &student);
        totals[3] += millis(start);
        let start = Instant::now();
        clip_global_norm(&student, &mut grads, config.grad_clip_norm)?;
        student = optimizer.step(schedule.lr(step), student, grads);
        teacher = ema_update(teacher, &student.valid(), config.ema_base)?;
        totals[4] += millis(start);
    }
    Ok(PHASES
        .into_iter()
        .zip(totals)
        .map(|(name, total)| (name, total / steps as f64))
        .collect())
}

/// The first three phases of a step on `batch` (teacher forward, student
/// forward, loss), each one's milliseconds added to its entry of
/// `totals`; returns the loss's total.
fn timed_loss(
    teacher: &StereoNetwork,
    student: &StereoNetwork,
    loss: &S3Loss,
    batch: StepBatch,
    totals: &mut [f64; 5],
) -> Result<Tensor<1>, BoxError> {
    let start = Instant::now();
    let teacher_disparity = predict(
        teacher,
        batch.reference.clone(),
        batch.teacher_target.clone(),
        &batch.teacher_sides,
    );
    totals[0] += millis(start);
    let start = Instant::now();
    let student_disparity = predict(
        student,
        batch.augmented_reference,
        batch.augmented_target,
        &batch.student_sides,
    );
    totals[1] += millis(start);
    let start = Instant::now();
    let out = loss.compute(LossInputs {
        geometry_weight: 1.0,
        reference: batch.reference,
        student_target: batch.student_target,
        teacher_target: batch.teacher_target,
        student_disparity,
        teacher_disparity,
        student_sides: batch.student_sides,
        teacher_sides: batch.teacher_sides,
        ratios: batch.ratios,
    })?;
    // The step reads the loss back; so does this.
    out.total.clone().into_data();
    totals[2] += millis(start);
    Ok(out.total)
}

/// Takes the warm-up steps, the timed ones and (with `--breakdown`) the
/// ones taken apart; returns the JSON line to print.
fn run(args: &Args) -> Result<String, BoxError> {
    let device = mbs_nets::device::open_device(&args.device)?;
    let train_device = device.clone().autodiff();
    // Seeds the weights and the random images.
    train_device.seed(args.seed);
    device.seed(args.seed);
    args.check_breakdown()?;
    let network = args.network();
    let total_steps = args.warmup + 2 * args.steps;
    let config = TrainerConfig::new(LossConfig::new(), OneCycleConfig::new(2e-4, total_steps))
        .with_precision(args.precision);
    let student = network.init(&train_device)?;
    let mut trainer = S3Trainer::new(student.clone(), &config)?;
    let batch = batch(args, &device);
    for _ in 0..args.warmup {
        trainer.step(batch.clone())?;
    }
    let start = Instant::now();
    let mut loss = f32::NAN;
    for _ in 0..args.steps {
        loss = trainer.step(batch.clone())?.loss;
    }
    let ms_per_step = millis(start) / args.steps as f64;
    let parts = if args.breakdown {
        Some(breakdown(student, &config, &batch, args.steps)?)
    } else {
        None
    };
    json_line(args, ms_per_step, loss, parts)
}

/// The JSON line [`run`] prints: the settings, `ms_per_step`, the peak
/// memory, the thread count, the last `loss` (`null` when not finite) and
/// the breakdown's `parts`, if taken.
fn json_line(
    args: &Args,
    ms_per_step: f64,
    loss: f32,
    parts: Option<Vec<(&'static str, f64)>>,
) -> Result<String, BoxError> {
    let threads = std::env::var("RAYON_NUM_THREADS").unwrap_or_else(|_| "default".into());
    let rss = peak_rss_mib().map_or("null".to_string(), |mib| format!("{mib:.1}"));
    let loss = if loss.is_finite() {
        loss.to_string()
    } else {
        "null".to_string()
    };
    let mut line = format!(
        "{{\"framework\":\"burn\",\"device\":\"{}\",\"backbone\":\"{}\",\"batch\":{},\"height\":{},\"width\":{},\"max_disparity\":{},\
         \"precision\":\"{}\",\"ms_per_step\":{ms_per_step:.2},\"peak_rss_mib\":{rss},\"steps\":{},\"warmup\":{},\
         \"rayon_threads\":\"{threads}\",\"loss\":{loss}",
        args.device,
        args.backbone,
        args.batch,
        args.height,
        args.width,
        args.max_disparity,
        args.precision,
        args.steps,
        args.warmup,
    );
    if let Some(parts) = parts {
        line.push_str(",\"breakdown_ms\":{");
        for (i, (name, ms)) in parts.iter().enumerate() {
            let comma = if i == 0 { "" } else { "," };
            write!(line, "{comma}\"{name}\":{ms:.2}")?;
        }
        line.push('}');
    }
    line.push('}');
    Ok(line)
}

fn main() {
    let args = match Args::parse(std::env::args().skip(1)) {
        Ok(args) => args,
        Err(message) => {
            eprintln!("step_time: {message}");
            std::process::exit(2);
        }
    };
    match run(&args) {
        Ok(line) => println!("{line}"),
        Err(error) => {
            eprintln!("step_time: {error}");
            std::process::exit(1);
        }
    }
}
