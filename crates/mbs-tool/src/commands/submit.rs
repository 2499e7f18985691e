//! `mbs-tool submit`: a benchmark's test folder predicted by a disparity
//! source into the files its evaluation server accepts (KITTI, Middlebury
//! MiddEval3, ETH3D two-view; see `mbs_dataset::submission`), each pair
//! timed, then zipped for upload.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::anyhow;
use clap::Parser;
use mbs_core::formats::rgb;
use mbs_dataset::StereoPair;
use mbs_dataset::benchmark::Benchmark;
use mbs_dataset::pairs::PairSource;
use mbs_dataset::submission::SubmissionLayout;
use mbs_infer::SgmConfig;

use crate::cli::UsageError;
use crate::cli::batch::{self, Outcome};
use crate::cli::folders::{BenchmarkFolders, OneWithServer};
use crate::cli::source::{PairMatcher, StereoSourceArgs};

/// Arguments of `submit`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool submit --kitti /data/kitti2015/testing --checkpoint runs/s3 --out sub-kitti15
  mbs-tool submit --middlebury /data/MiddEval3/testH --name S3RAFT \\
      --backbone raft-stereo --weights s3.safetensors --device cuda --out sub-mb
  mbs-tool submit --eth3d /data/ETH3D/two_view_test --checkpoint runs/s3 --out sub-eth3d

Writes what each server documents: KITTI 2015 <out>/disp_0/<frame>.png
(16-bit, disparity x 256, 0 = none), KITTI 2012 <out>/<frame>.png (its devkit
reads them at the archive's root), zipped as kitti_submission.zip (enter the
time per image in the server's form); Middlebury
<out>/<split>/<Scene>/disp0<NAME>.pfm (disp0<NAME>_s.pfm with --no-fill, a
sparse map) and time<NAME>.txt (seconds), <split> named as the input folder,
zipped as middlebury_submission.zip with every split of NAME under --out (run
testH and trainingH with the same --out: the second run's archive holds
both); ETH3D <out>/low_res_two_view/<scene>.pfm and <scene>.txt ('runtime
SECONDS'), zipped as eth3d_submission.zip. Pairs run one at a time and each
prediction is timed alone (reading the images excluded); the mean time is
printed at the end. Finished pairs are skipped (a file cut short is
recomputed), so an interrupted run resumes; the archive is made when every
pair is done. An output that would replace one of the files read (a view,
ground truth, mask or calib.txt), or a file in --out that mbs did not write
(a dataset's own disp0GTy.pfm or KITTI ground truth; OUT/.mbs-written lists
what mbs wrote), is refused before anything is written, whatever the flags.")]
pub struct Args {
    /// What predicts the pairs.
    #[command(flatten)]
    pub source: StereoSourceArgs,
    /// The benchmark's test folder (KITTI, Middlebury or ETH3D).
    #[command(flatten)]
    pub folders: BenchmarkFolders<OneWithServer>,
    /// The method's name in Middlebury's file names (letters and digits).
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Whether earlier outputs are recomputed.
    #[command(flatten)]
    pub overwrite: crate::cli::flags::Overwrite,
}

/// Runs `submit`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (benchmark, dir, layout) = layout(&args)?;
    let pairs = PairSource::Benchmark {
        benchmark,
        dir: dir.clone(),
    }
    .pairs()?;
    args.source.refuse_unused_device()?;
    let ids: Vec<String> = pairs.iter().map(|p| p.id.clone()).collect();
    let mut inputs = mbs_dataset::stereo_pair::input_files(&pairs);
    args.source.add_files_to(&mut inputs);
    let outputs = layout.outputs(&args.out, &ids);
    let matcher = args.source.matcher(SgmConfig::default())?;
    let settings = serde_json::json!({ "source": args.source.settings()? });
    let out = crate::cli::take_out_settled(
        &args.out,
        None,
        "submit",
        (&inputs, &outputs),
        &settings,
        args.overwrite.overwrite,
    )?;
    let seconds = std::sync::Mutex::new(Vec::new());
    let summary = batch::run_in_order(
        &pairs,
        "pairs",
        |p| p.reference.display().to_string(),
        |pair| {
            let outcome = submit_one(&args, &layout, &matcher, pair)?;
            if let Some(s) = outcome.1 {
                seconds
                    .lock()
                    .map_err(|_| anyhow!("a timing thread panicked"))?
                    .push(s);
            }
            Ok(outcome.0)
        },
    );
    summary.finish("submit", "pairs")?;
    let archive = layout.archive(&args.out, &ids, &|path| out.written().lists(path))?;
    let seconds = seconds.into_inner().unwrap_or_default();
    if !seconds.is_empty() {
        eprintln!(
            "submit: {:.3} s per pair on average ({} timed)",
            seconds.iter().sum::<f64>() / seconds.len() as f64,
            seconds.len()
        );
    }
    println!("{}", archive.display());
    Ok(())
}

/// The benchmark, folder and submission layout the flags name; Middlebury
/// without `--name` is a usage error.
fn layout(args: &Args) -> anyhow::Result<(Benchmark, PathBuf, SubmissionLayout)> {
    let (benchmark, dir) = args.folders.first().ok_or_else(|| {
        UsageError(format!(
            "nothing to submit: give {} DIR",
            crate::cli::folders::flags_in_words::<crate::cli::folders::OneWithServer>()
        ))
    })?;
    if benchmark == Benchmark::Middlebury && args.name.is_none() {
        return Err(UsageError(
            "--middlebury needs --name NAME, the method's name in the file names".into(),
        )
        .into());
    }
    let layout =
        SubmissionLayout::for_folder(benchmark, dir, args.name.as_deref(), args.source.no_fill)?;
    Ok((benchmark, dir.clone(), layout))
}

/// Predicts one pair and writes its files, or skips it when they are
/// there; with the seconds the prediction took.
fn submit_one(
    args: &Args,
    layout: &SubmissionLayout,
    matcher: &PairMatcher,
    pair: &StereoPair,
) -> anyhow::Result<(Outcome, Option<f64>)> {
    let out: &Path = &args.out;
    if !args.overwrite.overwrite && layout.is_written(out, &pair.id) {
        return Ok((Outcome::Skipped, None));
    }
    let reference = rgb::read_rgb(&pair.reference)?;
    let target = rgb::read_rgb(&pair.target)?;
    let start = Instant::now();
    let prediction = matcher.predict(pair, &reference, &target)?;
    let seconds = start.elapsed().as_secs_f64();
    layout.write(out, &pair.id, &prediction.disparity, seconds)?;
    Ok((Outcome::Done, Some(seconds)))
}
