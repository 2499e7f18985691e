//! `mbs-tool demo`: the whole pipeline on built-in synthetic data, each step
//! printed as the command a user would type.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Parser;
use mbs_core::formats::{DisparityFormat, pfm, png16, rgb};
use mbs_core::metrics::{MetricsReport, evaluate};
use mbs_dataset::Manifest;
use mbs_dataset::mbs20k::{Counts, decoded_disparity_file};
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

/// Runs `demo`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let data = args.out.join("data");
    let decoded = args.out.join("decoded");
    let manifest = data.join("manifest.json");
    let (data_s, decoded_s, manifest_s) = (
        data.display().to_string(),
        decoded.display().to_string(),
        manifest.display().to_string(),
    );
    let frames = args.frames.to_string();

    let synth_args = strings(&[
        "synth",
        "--out",
        &data_s,
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

    let validate_args = strings(&["validate", &manifest_s, "--deep"]);
    step(
        "2. Validate it against the schema and the files on disk",
        &validate_args,
    );
    validate::run(validate::Args::try_parse_from(&validate_args)?)?;

    let decode_args = strings(&[
        "decode-depth",
        &manifest_s,
        "--out",
        &decoded_s,
        "--all-pairs",
    ]);
    step(
        "3. Decode the CARLA depth PNGs into metres and disparity",
        &decode_args,
    );
    decode_depth::run(decode_depth::Args::try_parse_from(&decode_args)?)?;

    eprintln!("\n== 4. Check: decoded disparity against the renderer's exact ground truth");
    let manifest_data = Manifest::load(&manifest)?;
    let (epe, pixels) = decoded_vs_ground_truth(&manifest_data, &data, &decoded)?;
    eprintln!(
        "pair 0:4 over {pixels} pixels nearer than 200 m: EPE {epe:.4} px (KITTI PNG quantisation is 1/256 px)"
    );

    let sample = data.join(&manifest_data.samples[0].id);
    let extrapolated = args.out.join("extrapolated");
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
        &extrapolated.display().to_string(),
        "--preview",
    ]);
    step(
        "5. Extrapolate cameras 0 and 3 from the pair (1, 2) with the built-in matcher",
        &extrapolate_args,
    );
    extrapolate::run(extrapolate::Args::try_parse_from(&extrapolate_args)?)?;
    for (new, rendered) in [("image_1.png", 0), ("image_4.png", 3)] {
        let ours = rgb::read_rgb(&extrapolated.join(new))?;
        let truth = rgb::read_rgb(&sample.join(mbs_dataset::mbs20k::view_file(rendered)))?;
        let db = psnr(&ours, &truth, None).context("views of different sizes")?;
        eprintln!("{new} vs rendered camera {rendered}: PSNR {db:.2} dB");
    }

    train_and_evaluate(&args)?;

    println!(
        "\nSets per town and weather:\n{}",
        Counts::of(&manifest_data).table()
    );
    println!("Outputs:");
    println!(
        "  {}/<Town>/<Weather>/<frame>/rgb_0..4.png, depth_0.png, gt/   views and ground truth",
        data.display()
    );
    println!(
        "  {}                                           the manifest",
        manifest.display()
    );
    println!(
        "  {}/<Town>/<Weather>/<frame>/depth_0.exr, disp_0_T.png   decoded depth and disparity",
        decoded.display()
    );
    println!(
        "  {}/image_1.png, image_4.png, mask_*.png, preview.png   extrapolated views",
        extrapolated.display()
    );
    println!(
        "  {}/loss.png, val.png, visuals/, checkpoints/        the training run",
        args.out.join("run").display()
    );
    Ok(())
}

/// Steps 6 and 7: a short S3 run on small synthetic scenes (two training
/// towns, Town10 held out) and the trained teacher's scores.
fn train_and_evaluate(args: &Args) -> anyhow::Result<()> {
    let data = args.out.join("train-data");
    let run = args.out.join("run");
    let manifest = data.join("manifest.json").display().to_string();
    let synth_args = strings(&[
        "synth",
        "--out",
        &data.display().to_string(),
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
    let train_args = strings(&[
        "train",
        &manifest,
        "--out",
        &run.display().to_string(),
        "--steps",
        &steps,
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
    ]);
    step(
        "6b. Train the built-in network with S3, no ground truth (about a minute)",
        &train_args,
    );
    train::run(train::Args::try_parse_from(&train_args)?)?;

    let eval_args = strings(&[
        "eval",
        "--checkpoint",
        &run.display().to_string(),
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
        images.push((sample.id.clone(), evaluate(&ours, &gt, None, &[])?));
    }
    // EPE is over the pixels the decoder kept (nearer than --max-depth).
    let all = MetricsReport::new(images).pooled().all.metrics();
    let kept = all.density.unwrap_or(0.0) / 100.0 * all.pixels as f64;
    Ok((all.epe.unwrap_or(f64::NAN), kept.round() as usize))
}
