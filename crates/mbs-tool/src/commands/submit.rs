//! `mbs-tool submit`: a benchmark's test folder predicted by a disparity
//! source into the files its evaluation server accepts (KITTI, Middlebury
//! MiddEval3, ETH3D two-view; see `mbs_dataset::submission`), each pair
//! timed, then zipped for upload.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, anyhow, bail};
use clap::Parser;
use mbs_core::formats::rgb;
use mbs_dataset::benchmark::Benchmark;
use mbs_dataset::kitti::KittiFolder;
use mbs_dataset::pairs::{PairSource, StereoPair};
use mbs_dataset::submission::SubmissionLayout;
use mbs_infer::SgmConfig;

use crate::cli::batch::{self, Outcome};
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
ground truth, mask or calib.txt) is refused before anything is written.")]
pub struct Args {
    /// What predicts the pairs.
    #[command(flatten)]
    pub source: StereoSourceArgs,
    /// A KITTI 2015 or 2012 testing folder (its *_10 frames).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["middlebury", "eth3d"], required_unless_present_any = ["middlebury", "eth3d"])]
    pub kitti: Option<PathBuf>,
    /// A MiddEval3 split folder (testF, testH, testQ or a training one).
    #[arg(long, value_name = "DIR", requires = "name", conflicts_with = "eth3d")]
    pub middlebury: Option<PathBuf>,
    /// An ETH3D two_view_test folder.
    #[arg(long, value_name = "DIR")]
    pub eth3d: Option<PathBuf>,
    /// The method's name in Middlebury's file names (letters and digits).
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Recompute pairs whose files already exist.
    #[arg(long)]
    pub overwrite: bool,
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
    let inputs = mbs_dataset::pairs::input_files(&pairs);
    for output in layout.outputs(&args.out, &ids) {
        inputs.refuse(&output)?;
    }
    let matcher = args.source.matcher(SgmConfig::default())?;
    crate::cli::prepare_out(&args.out)?;
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
    let archive = layout.archive(&args.out, &ids)?;
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

/// The benchmark, folder and submission layout the flags name.
fn layout(args: &Args) -> anyhow::Result<(Benchmark, PathBuf, SubmissionLayout)> {
    if let Some(dir) = &args.kitti {
        let version = KittiFolder::open(dir)?.version;
        return Ok((
            Benchmark::Kitti,
            dir.clone(),
            SubmissionLayout::Kitti(version),
        ));
    }
    if let Some(dir) = &args.middlebury {
        let split = dir
            .canonicalize()
            .with_context(|| format!("the Middlebury folder {}", dir.display()))?;
        let split = split
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .ok_or_else(|| anyhow!("{}: not a MiddEval3 split folder", dir.display()))?;
        let method = args.name.as_deref().unwrap_or_default();
        let layout = SubmissionLayout::middlebury(method, &split, args.source.no_fill)
            .map_err(|e| anyhow!(e))?;
        return Ok((Benchmark::Middlebury, dir.clone(), layout));
    }
    match &args.eth3d {
        Some(dir) => Ok((Benchmark::Eth3d, dir.clone(), SubmissionLayout::Eth3d)),
        None => bail!("nothing to submit: give --kitti, --middlebury or --eth3d DIR"),
    }
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
    if !args.overwrite && layout.is_written(out, &pair.id) {
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
