//! `mbs-tool benchmark`: one disparity source scored zero-shot on several
//! benchmarks' folders at once under one scoring protocol — by default the
//! S3 paper's (stereo_toolbox: Out-3 on KITTI and DrivingStereo, Out-2 on
//! Middlebury, Out-1 on ETH3D, per-image percentages averaged over the
//! images) — printed as the paper's Table 4 (OCC and ALL per benchmark).

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::Parser;
use mbs_core::atomic::{refuse_special_target, write_bytes_atomic};
use mbs_core::inputs::InputFiles;
use mbs_dataset::StereoPair;
use mbs_dataset::benchmark::Benchmark;
use mbs_dataset::pairs::PairSource;
use mbs_eval::{FrameList, Listing, Protocol, ProtocolReport, Region, Rules, check_listed, items};
use mbs_infer::SgmConfig;
use serde_json::{Value, json};

use crate::cli::folders::{BenchmarkFolders, Every};
use crate::cli::scoring::{score_with_bar, warn_unscored};
use crate::cli::source::StereoSourceArgs;

/// Arguments of `benchmark`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool benchmark --backbone raft-stereo --weights raftstereo-sceneflow.pth \\
      --kitti /data/kitti2015/training --kitti /data/kitti2012/training \\
      --middlebury /data/MiddEval3/trainingH --eth3d /data/ETH3D/two_view_training \\
      --drivingstereo /data/DrivingStereo/sunny --drivingstereo /data/DrivingStereo/rainy
  mbs-tool benchmark --checkpoint runs/s3 --kitti /data/kitti2015/training --json
  mbs-tool benchmark --middlebury MiddEval3/trainingQ --per-image scores.json   # the built-in matcher

  mbs-tool benchmark --kitti kitti2012/training --frames kitti2012/training=train_all.txt \\
      --kitti kitti2015/training --protocol pixels

Every folder is read as its benchmark's download unpacks (see `mbs-tool eval
--help` for the layouts) and scored under --protocol: s3 (the paper's
stereo_toolbox, the default), pixels (mbs's pooled figures), raft-stereo,
igev-stereo, kitti, eth3d or middlebury (docs/evaluation.md), each with its
benchmark's threshold; --threshold sets one for all. Each flag may be given
several times (KITTI 2012 and 2015, DrivingStereo's weathers), each folder a
column. OCC is '-' where the benchmark has no occlusion mask (DrivingStereo,
SceneFlow) or the protocol does not score it. A folder that does not match
its layout stops the command before anything is scored; an image that fails
is reported and counted, and the others are scored; frames without usable
ground truth are named in a warning.")]
pub struct Args {
    /// What predicts the pairs.
    #[command(flatten)]
    pub source: StereoSourceArgs,
    /// The benchmark folders scored, each a column (each flag may be
    /// repeated).
    #[command(flatten)]
    pub folders: BenchmarkFolders<Every>,
    /// Out-x threshold in pixels for every benchmark instead of each one's
    /// customary one.
    #[arg(long, value_name = "PX", value_parser = crate::cli::values::positive_f32)]
    pub threshold: Option<f32>,
    /// The scoring rules: s3 (the S3 paper's stereo_toolbox), pixels
    /// (mbs's, pooled over pixels) or a project's own (docs/evaluation.md).
    #[arg(long, default_value = "s3", value_parser = crate::cli::values::protocol())]
    pub protocol: Protocol,
    /// Score only the frames a file names, one a line (blank lines and #
    /// comments ignored): DIR=FILE for the folder DIR (one given to a
    /// folder flag, however spelled), FILE for every folder without one of
    /// its own (each name must be in one of them). May be repeated.
    #[arg(long, value_name = "[DIR=]FILE")]
    pub frames: Vec<String>,
    /// Print JSON instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// Write every image's scores, per folder, to this JSON file.
    #[arg(long, value_name = "FILE")]
    pub per_image: Option<PathBuf>,
    /// Worker threads.
    #[command(flatten)]
    pub threads: crate::cli::flags::Jobs,
}

/// One benchmark folder's scores.
struct Column {
    /// The column's name: the benchmark and the folder.
    label: String,
    /// The rules its images are scored under.
    rules: Rules,
    /// The images scored.
    report: Option<ProtocolReport>,
    /// Images that failed.
    failed: usize,
    /// Frames without usable ground truth, not scored.
    unscored: Vec<String>,
}

/// Runs `benchmark`.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.threads.start()?;
    let (listed, inputs) = list_folders(&args)?;
    if let Some(path) = &args.per_image {
        inputs.refuse(path)?;
        refuse_special_target(path)?;
    }
    args.source.refuse_unused_device()?;
    let matcher = args.source.matcher(SgmConfig::default())?;
    let mut columns = Vec::new();
    for folder in listed {
        let Folder {
            label,
            rules,
            listing,
        } = folder;
        eprintln!("{label}: {} images", listing.pairs.len());
        let items = items(listing.pairs, None);
        let (scored, summary) = score_with_bar(&items, Some(&matcher), None, &rules);
        let scored = scored.images;
        columns.push(Column {
            report: (!scored.is_empty()).then(|| ProtocolReport::new(rules.clone(), scored)),
            label,
            rules,
            failed: summary.failed,
            unscored: listing.unscored,
        });
    }
    if let Some(path) = &args.per_image {
        let per_image: serde_json::Map<String, Value> = columns
            .iter()
            .filter_map(|c| Some((c.label.clone(), c.report.as_ref()?.json())))
            .collect();
        write_json(path, &Value::Object(per_image))?;
    }
    print_columns(&args, matcher.name(), &columns);
    finish(&columns)
}

/// Prints the columns: JSON, or the table and the paper's row.
fn print_columns(args: &Args, source: &str, columns: &[Column]) {
    if args.json {
        let rows: Vec<Value> = columns.iter().map(column_json).collect();
        println!(
            "{:#}",
            json!({ "source": source, "protocol": args.protocol.name(), "benchmarks": rows })
        );
    } else {
        println!("{source}");
        println!("protocol {}: {}", args.protocol, args.protocol.source());
        print!("{}", table(columns));
        print!("{}", paper_row(columns));
    }
}

/// Names the frames left unscored, then fails when an image failed.
fn finish(columns: &[Column]) -> anyhow::Result<()> {
    for c in columns {
        warn_unscored(&c.label, &c.unscored);
    }
    let failed: usize = columns.iter().map(|c| c.failed).sum();
    if failed > 0 {
        bail!("{failed} images failed (see above); the others are scored");
    }
    Ok(())
}

/// A folder to score: its column name, its rules and its pairs.
struct Folder {
    /// The column's name.
    label: String,
    /// The protocol's rules for its benchmark.
    rules: Rules,
    /// Its pairs with ground truth (the listed ones) and the unscored.
    listing: Listing,
}

/// Every folder the flags give, in flag order, with its rules and pairs
/// (only the frames `--frames` lists), and every file they read; all are
/// listed before anything is predicted, so that a folder off its layout, a
/// protocol without rules for it or a listed frame that is nowhere stops
/// the command at once.
fn list_folders(args: &Args) -> anyhow::Result<(Vec<Folder>, InputFiles)> {
    let folders = &args.folders.folders;
    let lists = FrameLists::read(&args.frames, folders)?;
    let mut listed = Vec::new();
    for &(benchmark, ref dir) in folders {
        let source = PairSource::Benchmark {
            benchmark,
            dir: dir.clone(),
        };
        let mut rules = args.protocol.rules(source.dataset())?;
        if let Some(x) = args.threshold {
            rules = rules.with_thresholds(&[x]);
        }
        let listing = Listing::of(&source)
            .with_context(|| format!("{benchmark} folder {}", dir.display()))?;
        listed.push((benchmark.label(dir), rules, listing));
    }
    lists.check(folders, &listed)?;
    let mut inputs = InputFiles::new();
    inputs.extend(lists.bound.iter().map(|(_, list)| &list.path));
    inputs.extend(lists.shared.iter().map(|list| &list.path));
    args.source.add_files_to(&mut inputs);
    let mut kept = Vec::new();
    for ((_, dir), (label, rules, listing)) in folders.iter().zip(listed) {
        let listing = match lists.for_folder(dir) {
            Some(list) => listing.keep(list),
            None => listing,
        };
        inputs.extend(listing.pairs.iter().flat_map(StereoPair::input_files));
        kept.push(Folder {
            label,
            rules,
            listing,
        });
    }
    Ok((kept, inputs))
}

/// The `--frames` lists: those bound to a folder (`DIR=FILE`) and the
/// one for every other folder (`FILE`).
struct FrameLists {
    bound: Vec<(PathBuf, FrameList)>,
    shared: Option<FrameList>,
}

impl FrameLists {
    /// Reads the `specs` against the `folders` given: `DIR=FILE` when DIR
    /// is one of them, else FILE; two lists for one folder, or two shared
    /// lists, are an error.
    fn read(specs: &[String], folders: &[(Benchmark, PathBuf)]) -> anyhow::Result<FrameLists> {
        let mut lists = FrameLists {
            bound: Vec::new(),
            shared: None,
        };
        for spec in specs {
            let bound = spec.split_once('=').and_then(|(dir, file)| {
                let folder = folders
                    .iter()
                    .find(|(_, d)| same_folder(d, Path::new(dir)))?;
                Some((&folder.1, file))
            });
            match bound {
                Some((folder, file)) => {
                    if lists.bound.iter().any(|(d, _)| d == folder) {
                        bail!("--frames: two lists for the folder {}", folder.display());
                    }
                    let list = FrameList::read(Path::new(file))?;
                    lists.bound.push((folder.clone(), list));
                }
                None if lists.shared.is_some() => {
                    bail!(
                        "--frames: two lists for every folder ({spec} and another); give DIR=FILE"
                    )
                }
                None => lists.shared = Some(FrameList::read(Path::new(spec))?),
            }
        }
        Ok(lists)
    }

    /// The list that applies to the folder `dir`, if any.
    fn for_folder(&self, dir: &Path) -> Option<&FrameList> {
        self.bound
            .iter()
            .find(|(d, _)| d == dir)
            .map(|(_, l)| l)
            .or(self.shared.as_ref())
    }

    /// An error naming the listed frames that none of the folders a list
    /// applies to has.
    fn check(
        &self,
        folders: &[(Benchmark, PathBuf)],
        listed: &[(String, Rules, Listing)],
    ) -> anyhow::Result<()> {
        let lists = self
            .bound
            .iter()
            .map(|(_, l)| l)
            .chain(self.shared.as_ref());
        for list in lists {
            let (names, listings): (Vec<String>, Vec<&Listing>) = folders
                .iter()
                .zip(listed)
                .filter(|((_, dir), _)| self.for_folder(dir) == Some(list))
                .map(|((_, dir), (_, _, listing))| (dir.display().to_string(), listing))
                .unzip();
            check_listed(list, &listings, &names.join(" or "))?;
        }
        Ok(())
    }
}

/// Whether `a` and `b` name one folder, however spelled (`k`, `./k`, a
/// link to it): the same path, or the same path once resolved.
fn same_folder(a: &Path, b: &Path) -> bool {
    a == b || matches!((a.canonicalize(), b.canonicalize()), (Ok(a), Ok(b)) if a == b)
}

/// The protocol's headline figure (percent) of `region` in a column, if
/// scored (NOC and OCC exist only where the ground truth has an occlusion
/// mask and the protocol scores them).
fn out_x(column: &Column, region: Region) -> Option<f64> {
    column.report.as_ref()?.headline(region)
}

/// The column's EPE, as the protocol combines it, if scored.
fn epe(column: &Column) -> Option<f64> {
    column.report.as_ref()?.epe()
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
        let images = c.report.as_ref().map_or(0, ProtocolReport::images);
        out += &format!(
            "{:<width$} {:>7} {:>7} {:>7} {:>8} {:>8} {:>8} {:>8}\n",
            c.label,
            c.rules.headline.name(),
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
            head += &format!(
                " {} {} {} |",
                c.label,
                region.name(),
                c.rules.headline.name()
            );
            rule += " ---: |";
            row += &format!(
                " {} |",
                out_x(c, region).map_or("-".to_string(), |v| format!("{v:.2}"))
            );
        }
    }
    format!("\nTable 4 row (Markdown):\n{head}\n{rule}\n{row}\n")
}

/// A column as JSON: the folder's OCC, NOC and ALL headline figures, its
/// EPE and the rules they were scored under.
fn column_json(c: &Column) -> Value {
    json!({
        "benchmark": c.label,
        "rules": c.rules.describe(),
        "metric": c.rules.headline.key(),
        "images": c.report.as_ref().map_or(0, ProtocolReport::images),
        "failed": c.failed,
        "unscored": c.unscored,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_list_binds_to_its_folder_however_the_folder_is_spelled() {
        let dir = tempfile::tempdir().unwrap();
        let kitti = dir.path().join("k15");
        std::fs::create_dir(&kitti).unwrap();
        let list = dir.path().join("one.txt");
        std::fs::write(&list, "000001_10\n").unwrap();
        let folders = [(Benchmark::Kitti, kitti.clone())];
        let spelled = dir.path().join(".").join("k15");
        let spec = format!("{}={}", spelled.display(), list.display());
        let lists = FrameLists::read(std::slice::from_ref(&spec), &folders).unwrap();
        assert!(lists.shared.is_none());
        assert_eq!(
            lists.for_folder(&kitti).map(|l| &l.names[..]),
            Some(&["000001_10".to_string()][..])
        );
        let twice = FrameLists::read(&[spec.clone(), spec], &folders)
            .err()
            .unwrap();
        assert!(
            twice.to_string().contains("two lists for the folder"),
            "{twice}"
        );
    }
}
