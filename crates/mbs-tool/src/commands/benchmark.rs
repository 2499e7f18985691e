//! `mbs-tool benchmark`: one disparity source scored zero-shot on several
//! benchmarks' folders at once, each with its customary metric (Out-3 on
//! KITTI and DrivingStereo, Out-2 on Middlebury, Out-1 on ETH3D and
//! SceneFlow), printed as the S3 paper's Table 4 (OCC and ALL per
//! benchmark).

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::Parser;
use mbs_core::atomic::{refuse_special_target, write_bytes_atomic};
use mbs_core::inputs::InputFiles;
use mbs_core::metrics::{MetricsReport, Region};
use mbs_dataset::benchmark::Benchmark;
use mbs_dataset::kitti::KittiVersion;
use mbs_dataset::pairs::{PairSource, StereoPair};
use mbs_infer::SgmConfig;
use serde_json::{Value, json};

use crate::cli::source::StereoSourceArgs;
use crate::commands::eval::{Item, items, score_all};

/// Arguments of `benchmark`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool benchmark --backbone raft-stereo --weights raftstereo-sceneflow.pth \\
      --kitti /data/kitti2015/training --kitti /data/kitti2012/training \\
      --middlebury /data/MiddEval3/trainingH --eth3d /data/ETH3D/two_view_training \\
      --drivingstereo /data/DrivingStereo/sunny --drivingstereo /data/DrivingStereo/rainy
  mbs-tool benchmark --checkpoint runs/s3 --kitti /data/kitti2015/training --json
  mbs-tool benchmark --middlebury MiddEval3/trainingQ --per-image scores.json   # the built-in matcher

Every folder is read as its benchmark's download unpacks (see `mbs-tool eval
--help` for the layouts) and scored with that benchmark's metric and
threshold; --threshold sets one for all. Each flag may be given several
times (KITTI 2012 and 2015, DrivingStereo's weathers), each folder a column.
Scores are pooled over the pixels of a folder's images; OCC is '-' where the
benchmark has no occlusion mask (DrivingStereo, SceneFlow). A folder that
does not match its layout stops the command before anything is scored; an
image that fails is reported and counted, and the others are scored.")]
pub struct Args {
    /// What predicts the pairs.
    #[command(flatten)]
    pub source: StereoSourceArgs,
    /// KITTI 2015 or 2012 training folders (their *_10 frames).
    #[arg(long, value_name = "DIR")]
    pub kitti: Vec<PathBuf>,
    /// Middlebury 2014 / MiddEval3 folders of scenes (e.g. trainingH, the
    /// paper's half resolution).
    #[arg(long, value_name = "DIR")]
    pub middlebury: Vec<PathBuf>,
    /// ETH3D two_view_training folders (ground truth from the sibling
    /// two_view_training_gt).
    #[arg(long, value_name = "DIR")]
    pub eth3d: Vec<PathBuf>,
    /// DrivingStereo weather folders (sunny, cloudy, foggy, rainy).
    #[arg(long, value_name = "DIR")]
    pub drivingstereo: Vec<PathBuf>,
    /// SceneFlow folders (a dataset folder or one inside a pass, e.g.
    /// frames_finalpass/TEST).
    #[arg(long, value_name = "DIR")]
    pub sceneflow: Vec<PathBuf>,
    /// Out-x threshold in pixels for every benchmark instead of each one's
    /// customary one.
    #[arg(long, value_name = "PX", value_parser = crate::cli::values::positive_f32)]
    pub threshold: Option<f32>,
    /// Print JSON instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// Write every image's scores, per folder, to this JSON file.
    #[arg(long, value_name = "FILE")]
    pub per_image: Option<PathBuf>,
    /// Worker threads (0 = one per core).
    #[arg(long, default_value_t = 0, value_parser = crate::cli::values::jobs)]
    pub jobs: usize,
}

/// One benchmark folder's scores.
struct Column {
    /// The column's name: the benchmark and the folder.
    label: String,
    /// The metric's threshold.
    threshold: f32,
    /// The images scored, pooled.
    report: Option<MetricsReport>,
    /// Images that failed.
    failed: usize,
}

/// Runs `benchmark`.
pub fn run(args: Args) -> anyhow::Result<()> {
    crate::cli::set_threads(args.jobs)?;
    let (listed, inputs) = list_folders(&args)?;
    if let Some(path) = &args.per_image {
        inputs.refuse(path)?;
        refuse_special_target(path)?;
    }
    args.source.refuse_unused_device()?;
    let matcher = args.source.matcher(SgmConfig::default())?;
    let mut columns = Vec::new();
    for (benchmark, dir, items) in listed {
        let label = label(benchmark, dir);
        let threshold = args
            .threshold
            .unwrap_or_else(|| benchmark.customary_threshold());
        eprintln!("{label}: {} images", items.len());
        let (scored, summary) = score_all(&items, Some(&matcher), None, &[threshold]);
        columns.push(Column {
            label,
            threshold,
            report: (!scored.is_empty()).then(|| MetricsReport::new(scored)),
            failed: summary.failed,
        });
    }
    if let Some(path) = &args.per_image {
        let per_image: serde_json::Map<String, Value> = columns
            .iter()
            .filter_map(|c| Some((c.label.clone(), c.report.as_ref()?.json())))
            .collect();
        write_json(path, &Value::Object(per_image))?;
    }
    if args.json {
        let rows: Vec<Value> = columns.iter().map(column_json).collect();
        println!(
            "{:#}",
            json!({ "source": matcher.name(), "benchmarks": rows })
        );
    } else {
        println!("{}", matcher.name());
        print!("{}", table(&columns));
        print!("{}", paper_row(&columns));
    }
    let failed: usize = columns.iter().map(|c| c.failed).sum();
    if failed > 0 {
        bail!("{failed} images failed (see above); the others are scored");
    }
    Ok(())
}

/// The folders of [`list_folders`], each with its items to score.
type Listed<'a> = Vec<(Benchmark, &'a PathBuf, Vec<Item>)>;

/// Every folder the flags give, in flag order, with its items to score,
/// and every file they read; all are listed before anything is predicted,
/// so that a folder off its layout stops the command at once.
fn list_folders(args: &Args) -> anyhow::Result<(Listed<'_>, InputFiles)> {
    let folders: Vec<(Benchmark, &PathBuf)> = [
        (Benchmark::Kitti, &args.kitti),
        (Benchmark::Middlebury, &args.middlebury),
        (Benchmark::Eth3d, &args.eth3d),
        (Benchmark::DrivingStereo, &args.drivingstereo),
        (Benchmark::SceneFlow, &args.sceneflow),
    ]
    .into_iter()
    .flat_map(|(benchmark, dirs)| dirs.iter().map(move |dir| (benchmark, dir)))
    .collect();
    if folders.is_empty() {
        bail!(
            "no benchmark folder: give --kitti, --middlebury, --eth3d, --drivingstereo or \
             --sceneflow DIR (each may be repeated)"
        );
    }
    let mut inputs = InputFiles::new();
    let mut listed = Vec::new();
    for (benchmark, dir) in folders {
        let source = PairSource::Benchmark {
            benchmark,
            dir: dir.clone(),
        };
        let pairs = source
            .scored_pairs()
            .with_context(|| format!("{benchmark} folder {}", dir.display()))?;
        for file in pairs.iter().flat_map(StereoPair::input_files) {
            inputs.add(&file);
        }
        listed.push((benchmark, dir, items(pairs, None)));
    }
    Ok((listed, inputs))
}

/// A folder's column name: the benchmark (KITTI with its year) and the
/// folder's name, e.g. `KITTI 2015 training` or `DrivingStereo rainy`.
fn label(benchmark: Benchmark, dir: &Path) -> String {
    let name = dir.file_name().map_or_else(
        || dir.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    match KittiVersion::of_ground_truth(dir).filter(|_| benchmark == Benchmark::Kitti) {
        Some(version) => format!("{} {name}", version.name()),
        None => format!("{benchmark} {name}"),
    }
}

/// The pooled Out-x (percent) of `region` in a column, if scored (NOC and
/// OCC exist only where the ground truth has an occlusion mask).
fn out_x(column: &Column, region: Region) -> Option<f64> {
    let sums = column.report.as_ref()?.pooled().get(region)?;
    sums.metrics().out(column.threshold)
}

/// The pooled EPE of every valid pixel in a column, if scored.
fn epe(column: &Column) -> Option<f64> {
    column.report.as_ref()?.pooled().all.metrics().epe
}

/// One row per folder: metric, images, OCC, NOC, ALL and EPE.
fn table(columns: &[Column]) -> String {
    let width = columns.iter().map(|c| c.label.len()).max().unwrap_or(0);
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}%"));
    let mut out = format!(
        "{:<width$} {:>7} {:>7} {:>7} {:>8} {:>8} {:>8} {:>8}\n",
        "benchmark", "metric", "images", "failed", "OCC", "NOC", "ALL", "EPE"
    );
    for c in columns {
        let images = c.report.as_ref().map_or(0, MetricsReport::images);
        out += &format!(
            "{:<width$} {:>7} {:>7} {:>7} {:>8} {:>8} {:>8} {:>8}\n",
            c.label,
            format!("Out-{}", c.threshold),
            images,
            c.failed,
            pct(out_x(c, Region::Occ)),
            pct(out_x(c, Region::Noc)),
            pct(out_x(c, Region::All)),
            epe(c).map_or("-".to_string(), |v| format!("{v:.3}")),
        );
    }
    out
}

/// The scores as one row of the paper's Table 4, in Markdown: OCC and ALL
/// of each folder's metric, in percent.
fn paper_row(columns: &[Column]) -> String {
    let mut head = String::from("|");
    let mut rule = String::from("|");
    let mut row = String::from("|");
    for c in columns {
        for region in [Region::Occ, Region::All] {
            head += &format!(" {} {} Out-{} |", c.label, region.name(), c.threshold);
            rule += " ---: |";
            row += &format!(
                " {} |",
                out_x(c, region).map_or("-".to_string(), |v| format!("{v:.2}"))
            );
        }
    }
    format!("\nTable 4 row (Markdown):\n{head}\n{rule}\n{row}\n")
}

/// A column as JSON: the folder's pooled OCC, NOC and ALL scores.
fn column_json(c: &Column) -> Value {
    json!({
        "benchmark": c.label,
        "metric": format!("out{}", c.threshold),
        "images": c.report.as_ref().map_or(0, MetricsReport::images),
        "failed": c.failed,
        "occ": out_x(c, Region::Occ),
        "noc": out_x(c, Region::Noc),
        "all": out_x(c, Region::All),
        "epe": epe(c),
    })
}

/// Writes `value` to `path` atomically.
fn write_json(path: &Path, value: &Value) -> anyhow::Result<()> {
    let text = format!("{value:#}\n");
    write_bytes_atomic(path, text.as_bytes())
        .with_context(|| format!("writing the per-image scores to {}", path.display()))
}
