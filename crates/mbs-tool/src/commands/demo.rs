//! `mbs-tool demo`: the whole pipeline on built-in synthetic data, each step
//! printed as the command a user would type.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Parser;
use mbs_core::formats::{DisparityFormat, pfm, png16, rgb};
use mbs_dataset::Manifest;
use mbs_dataset::mbs20k::{Counts, decoded_disparity_file};
use mbs_eval::{Dataset, Frame, Protocol, ProtocolReport, Region};
use mbs_image::quality::psnr;

use super::{decode_depth, eval, extrapolate, synth, train, validate};

/// Arguments of `demo`.
#[derive(Parser)]
#[command(after_help = "Example:
  cargo run --release -p mbs-tool -- demo --out mbs-demo

Steps: synth (a small MBS20K-style dataset with exact ground truth) ->
validate (schema + files) -> decode-depth (CARLA depth -> metres and
disparity for every pair) -> a check of the decoded disparity against the
renderer's ground truth -> extrapolate (two new views from a stereo pair,
with the built-in matcher) compared with the rendered views -> train (a
short S3 run on a second, smaller synthetic set, with the validation error
falling) -> eval of the trained teacher on held-out scenes. Re-running
reuses finished outputs (the training run resumes or is skipped).")]
pub struct Args {
    /// Output folder.
    #[arg(long, default_value = "mbs-demo")]
    pub out: PathBuf,
    /// Scenes per town.
    #[arg(long, default_value_t = 2)]
    pub frames: usize,
    /// Steps of the training run.
    #[arg(long, default_value_t = 300)]
    pub train_steps: usize,
}

fn step(title: &str, command: &[String]) {
    eprintln!("\n== {title}\n$ mbs-tool {}", command.join(" "));
}

fn strings(args: &[&str]) -> Vec<String> {
    args.iter().map(|s| s.to_string()).collect()
}

/// Where the demo writes, under its `--out`.
struct Folders {
    data: PathBuf,
    manifest: PathBuf,
    decoded: PathBuf,
    extrapolated: PathBuf,
    run: PathBuf,
    train_data: PathBuf,
}

impl Folders {
    fn under(out: &Path) -> Self {
        let data = out.join("data");
        let train_data = out.join("train-data");
        Folders {
            manifest: data.join("manifest.json"),
            data,
            decoded: out.join("decoded"),
            extrapolated: out.join("extrapolated"),
            run: out.join("run"),
            train_data,
        }
    }
}

/// The flags of the demo's training run (step 6b) besides its manifest,
/// folder and steps: a small batch and crop, and a schedule for 300 steps.
const TRAIN_SETTINGS: [&str; 20] = [
    "--batch-size",
    "4",
    "--crop",
    "96x160",
    "--lr",
    "0.002",
    "--max-disparity",
    "64",
    "--val-every",
    "100",
    "--set",
    "trainer.ema_base=0.9",
    "--set",
    "trainer.lr.pct_start=0.1",
    "--set",
    "augment.occlusion_min_side=10",
    "--set",
    "augment.occlusion_max_side=30",
    "--set",
    "data.val_pairs=[[0,1],[2,1],[2,3]]",
];

/// Runs `demo`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let folders = Folders::under(&args.out);
    make_data(&args, &folders)?;
    let manifest = Manifest::load(&folders.manifest)?;
    eprintln!("\n== 4. Check: decoded disparity against the renderer's exact ground truth");
    let (epe, pixels) = decoded_vs_ground_truth(&manifest, &folders.data, &folders.decoded)?;
    eprintln!(
        "pair 0:4 over {pixels} pixels nearer than 200 m: EPE {epe:.4} px (KITTI PNG quantisation is 1/256 px)"
    );
    extrapolate_and_compare(&folders, &folders.data.join(&manifest.samples[0].id))?;
    train_and_evaluate(&args, &folders)?;
    println!(
        "\nSets per town and weather:\n{}",
        Counts::of(&manifest).table()
    );
    print_outputs(&folders);
    Ok(())
}

/// Steps 1 to 3: synthesise a small dataset, validate it and decode its
/// depth.
fn make_data(args: &Args, folders: &Folders) -> anyhow::Result<()> {
    let (data, decoded, manifest) = (
        folders.data.display().to_string(),
        folders.decoded.display().to_string(),
        folders.manifest.display().to_string(),
    );
    let frames = args.frames.to_string();
    let synth_args = strings(&[
        "synth",
        "--out",
        &data,
        "--frames",
        &frames,
        "--weathers",
        "ClearNoon,ClearSunset",
        "--width",
        "480",
        "--height",
        "270",
        "--focal",
        "240",
    ]);
    step(
        "1. Synthesise a small multi-baseline dataset (5 cameras, B = 0.5 m)",
        &synth_args,
    );
    synth::run(synth::Args::try_parse_from(&synth_args)?)?;

    let validate_args = strings(&["validate", &manifest, "--deep"]);
    step(
        "2. Validate it against the schema and the files on disk",
        &validate_args,
    );
    validate::run(validate::Args::try_parse_from(&validate_args)?)?;

    let decode_args = strings(&["decode-depth", &manifest, "--out", &decoded, "--all-pairs"]);
    step(
        "3. Decode the CARLA depth PNGs into metres and disparity",
        &decode_args,
    );
    decode_depth::run(decode_depth::Args::try_parse_from(&decode_args)?)
}

/// Step 5: cameras 0 and 3 of `sample` extrapolated from its pair (1, 2),
/// compared with the rendered ones.
fn extrapolate_and_compare(folders: &Folders, sample: &Path) -> anyhow::Result<()> {
    let view = |k: usize| {
        sample
            .join(mbs_dataset::mbs20k::view_file(k))
            .display()
            .to_string()
    };
    let extrapolate_args = strings(&[
        "extrapolate",
        "--left",
        &view(1),
        "--right",
        &view(2),
        "--out",
        &folders.extrapolated.display().to_string(),
        "--preview",
    ]);
    step(
        "5. Extrapolate cameras 0 and 3 from the pair (1, 2) with the built-in matcher",
        &extrapolate_args,
    );
    extrapolate::run(extrapolate::Args::try_parse_from(&extrapolate_args)?)?;
    for (new, rendered) in [("image_1.png", 0), ("image_4.png", 3)] {
        let ours = rgb::read_rgb(&folders.extrapolated.join(new))?;
        let truth = rgb::read_rgb(&sample.join(mbs_dataset::mbs20k::view_file(rendered)))?;
        let db = psnr(&ours, &truth, None).context("views of different sizes")?;
        eprintln!("{new} vs rendered camera {rendered}: PSNR {db:.2} dB");
    }
    Ok(())
}

/// Lists what the demo wrote.
fn print_outputs(folders: &Folders) {
    println!("Outputs:");
    println!(
        "  {}/<Town>/<Weather>/<frame>/rgb_0..4.png, depth_0.png, gt/   views and ground truth",
        folders.data.display()
    );
    println!(
        "  {}                                           the manifest",
        folders.manifest.display()
    );
    println!(
        "  {}/<Town>/<Weather>/<frame>/depth_0.exr, disp_0_T.png   decoded depth and disparity",
        folders.decoded.display()
    );
    println!(
        "  {}/image_1.png, image_4.png, mask_*.png, preview.png   extrapolated views",
        folders.extrapolated.display()
    );
    println!(
        "  {}/loss.png, val.png, visuals/, checkpoints/        the training run",
        folders.run.display()
    );
}

/// Steps 6 and 7: a short S3 run on small synthetic scenes (two training
/// towns, Town10 held out) and the trained teacher's scores.
fn train_and_evaluate(args: &Args, folders: &Folders) -> anyhow::Result<()> {
    let run = folders.run.display().to_string();
    let manifest = folders
        .train_data
        .join("manifest.json")
        .display()
        .to_string();
    let synth_args = strings(&[
        "synth",
        "--out",
        &folders.train_data.display().to_string(),
        "--frames",
        "6",
        "--towns",
        "Town01,Town02,Town10",
        "--weathers",
        "ClearNoon,ClearSunset",
        "--width",
        "192",
        "--height",
        "96",
        "--focal",
        "96",
        "--no-checksums",
    ]);
    step(
        "6a. Synthesise small scenes to train on (Town10 is held out for validation)",
        &synth_args,
    );
    synth::run(synth::Args::try_parse_from(&synth_args)?)?;

    let steps = args.train_steps.to_string();
    let mut train_args = strings(&["train", &manifest, "--out", &run, "--steps", &steps]);
    train_args.extend(strings(&TRAIN_SETTINGS));
    step(
        "6b. Train the built-in network with S3, no ground truth (about a minute)",
        &train_args,
    );
    train::run(train::Args::try_parse_from(&train_args)?)?;

    let eval_args = strings(&[
        "eval",
        "--checkpoint",
        &run,
        "--manifest",
        &manifest,
        "--pair",
        "0:1",
        "--split",
        "test",
    ]);
    step(
        "7. Score the trained teacher on the held-out scenes (pair 0:1)",
        &eval_args,
    );
    eval::run(eval::Args::try_parse_from(&eval_args)?)
}

/// Mean |decoded disparity - exact GT| for pair 0:4 over all samples.
fn decoded_vs_ground_truth(
    manifest: &Manifest,
    data: &Path,
    decoded: &Path,
) -> anyhow::Result<(f64, usize)> {
    let rules = Protocol::Pixels.rules(Dataset::Other)?;
    let mut images = Vec::with_capacity(manifest.samples.len());
    for sample in &manifest.samples {
        let mut gt = pfm::read_pfm_grey(
            &data
                .join(&sample.id)
                .join(mbs_synth::dataset::disparity_file(0)),
        )?;
        // The file holds one baseline's disparity; pair 0:4 spans four.
        gt.iter_mut().for_each(|d| *d *= 4.0);
        let ours = png16::read_kitti_disparity(
            &decoded
                .join(&sample.id)
                .join(decoded_disparity_file(0, 4, DisparityFormat::Png16)),
        )
        .with_context(|| format!("sample {}", sample.id))?;
        let frame = Frame {
            prediction: &ours,
            gt: &gt,
            noc: None,
            disparity_bound: None,
        };
        images.push((sample.id.clone(), rules.score(&frame)?));
    }
    // EPE is over the pixels the decoder kept (nearer than --max-depth),
    // pooled over the samples (the pixels protocol).
    let Some(all) = ProtocolReport::new(rules, images).summary(Region::All) else {
        return Ok((f64::NAN, 0));
    };
    let kept = all.metrics.density.unwrap_or(0.0) / 100.0 * all.metrics.pixels as f64;
    Ok((all.metrics.epe.unwrap_or(f64::NAN), kept.round() as usize))
}
