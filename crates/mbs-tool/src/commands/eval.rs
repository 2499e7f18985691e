//! `mbs-tool eval`: predicted disparities against ground truth — EPE,
//! Out-x and D1 over ALL, NOC and OCC pixels, per image, averaged per image
//! and pooled over pixels (SPEC §6).

use std::path::{Path, PathBuf};

use crate::cli::checkpoint::CheckpointMatcher;
use crate::cli::pair::parse_pair;
use crate::cli::report_error::describe_item;
use anyhow::{Context, bail};
use clap::Parser;
use mbs_core::formats::{read_disparity, rgb};
use mbs_core::metrics::{MeanMetrics, Metrics, Region, RegionSums, evaluate, valid_mask};
use mbs_core::{FloatImage, MaskImage};
use mbs_dataset::kitti::{KittiFolder, KittiVersion};
use mbs_dataset::manifest::resolve;
use mbs_dataset::{Manifest, Split};
use mbs_infer::StereoMatcher;
use rayon::prelude::*;
use serde_json::{Value, json};

/// Arguments of `eval`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool eval pred/disp_0 --kitti /data/kitti2015/training
  mbs-tool eval pred/im2.pfm --gt teddy/disp2.png --gt-scale 4 --json
  mbs-tool eval pred --manifest mbs-demo/manifest.json --pair 0:1
  mbs-tool eval --checkpoint mbs-demo/run --manifest mbs-demo/train-data/manifest.json --split test

Predictions are looked up as <PREDICTIONS>/<name>.pfm, .png (KITTI 16-bit)
or .exr, <name> being the GT file stem (KITTI) or the sample id (manifest).
With --checkpoint, the run's teacher network predicts every pair instead.
A missing prediction value (+inf/NaN, 0 in PNGs) counts as an outlier for
Out-x and D1 and is left out of EPE; the density column says how many
pixels had one. ALL = valid GT; NOC = valid non-occluded GT (KITTI
disp_noc, a --noc mask, or the manifest's occlusion mask); OCC = ALL - NOC.")]
pub struct Args {
    /// A folder of predicted disparities, or one file with --gt.
    #[arg(required_unless_present = "checkpoint")]
    pub predictions: Option<PathBuf>,
    /// Predict with the teacher of a training run (or of one of its
    /// checkpoints/step-N folders) instead of reading PREDICTIONS.
    #[arg(long, value_name = "RUN|CHECKPOINT", conflicts_with_all = ["predictions", "gt"])]
    pub checkpoint: Option<PathBuf>,
    /// A KITTI 2015 (disp_occ_0, disp_noc_0) or 2012 (disp_occ, disp_noc)
    /// training folder.
    #[arg(long, conflicts_with_all = ["gt", "manifest"])]
    pub kitti: Option<PathBuf>,
    /// Ground truth of a single prediction: PFM/EXR (+inf = unknown) or
    /// PNG/PGM (see --gt-scale).
    #[arg(long, conflicts_with = "manifest")]
    pub gt: Option<PathBuf>,
    /// Non-occluded mask for --gt (non-zero = non-occluded), e.g.
    /// Middlebury's nonocc.png.
    #[arg(long, requires = "gt")]
    pub noc: Option<PathBuf>,
    /// A dataset manifest whose samples have ground truth for --pair.
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// Camera pair of the manifest's ground truth, REFERENCE:TARGET.
    #[arg(long, default_value = "0:1", value_parser = parse_pair)]
    pub pair: (usize, usize),
    /// Only the manifest's samples of this split (train, val or test).
    #[arg(long, requires = "manifest", value_parser = parse_split)]
    pub split: Option<Split>,
    /// GT PNG/PGM codes per pixel of disparity [default: 256 for 16-bit
    /// images (KITTI), 1 for 8-bit ones; Middlebury 2003 quarter size: 4,
    /// Tsukuba: 16].
    #[arg(long)]
    pub gt_scale: Option<f32>,
    /// Out-x thresholds in pixels, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2,3")]
    pub thresholds: Vec<f32>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Worker threads (0 = one per core).
    #[arg(long, default_value_t = 0)]
    pub jobs: usize,
}

/// One image to score.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    /// Name in the table.
    pub name: String,
    /// The predicted disparity.
    pub prediction: Prediction,
    /// Ground truth over all valid pixels.
    pub gt: PathBuf,
    /// The ground truth is this times the file's values (manifests share
    /// one-baseline files between pairs).
    pub gt_factor: f32,
    /// Where the non-occluded pixels are.
    pub noc: Option<Noc>,
}

/// Where a prediction comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Prediction {
    /// A disparity file.
    File(PathBuf),
    /// A pair the `--checkpoint` network predicts.
    Pair {
        /// The reference view.
        reference: PathBuf,
        /// The target view.
        target: PathBuf,
        /// Whether the target lies left of the reference.
        target_on_left: bool,
    },
}

/// A source of the non-occluded mask.
#[derive(Debug, Clone, PartialEq)]
pub enum Noc {
    /// A non-occluded GT map (KITTI `disp_noc`): valid = non-occluded.
    Map(PathBuf),
    /// A mask, non-zero = non-occluded.
    Mask(PathBuf),
    /// A mask, non-zero = occluded (manifests).
    Occlusion(PathBuf),
}

/// Runs `eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    crate::cli::set_threads(args.jobs)?;
    let predictions = args.predictions.as_deref();
    let items = if let (Some(gt), Some(predictions)) = (&args.gt, predictions) {
        vec![Item {
            name: predictions.file_name().map_or_else(
                || predictions.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            ),
            prediction: Prediction::File(predictions.to_path_buf()),
            gt: gt.clone(),
            gt_factor: 1.0,
            noc: args.noc.clone().map(Noc::Mask),
        }]
    } else if let Some(dir) = &args.kitti {
        kitti_items(dir, predictions)?
    } else if let Some(manifest) = &args.manifest {
        manifest_items(manifest, args.pair, args.split, predictions)?
    } else {
        bail!("no ground truth: give --kitti DIR, --gt FILE or --manifest FILE");
    };
    let network = args
        .checkpoint
        .as_deref()
        .map(CheckpointMatcher::open)
        .transpose()?;
    let results: Vec<anyhow::Result<RegionSums>> = items
        .par_iter()
        .map(|item| {
            let prediction = predict(&item.prediction, network.as_ref())?;
            score(item, &prediction, args.gt_scale, &args.thresholds)
        })
        .collect();
    let mut scored = Vec::new();
    let mut failed = 0;
    for (item, result) in items.iter().zip(results) {
        match result {
            Ok(sums) => scored.push((item.name.clone(), sums)),
            Err(e) => {
                eprintln!("error: {}", describe_item(&item.name, &e));
                failed += 1;
            }
        }
    }
    if scored.is_empty() {
        bail!("no image could be scored (see above)");
    }
    let report = Report::new(scored);
    if args.json {
        println!("{:#}", report.json());
    } else {
        print!("{}", report.table(&args.thresholds));
    }
    if failed > 0 {
        bail!("{failed} of {} images failed (see above)", items.len());
    }
    Ok(())
}

/// A split by its manifest name (the names `Split` is serialised with).
fn parse_split(text: &str) -> Result<Split, String> {
    serde_json::from_value(Value::from(text))
        .map_err(|_| format!("`{text}` is not a split: train, val or test"))
}

/// Finds a prediction `<dir>/<name>.{pfm,png,exr}`.
fn find_prediction(dir: &Path, name: &str) -> anyhow::Result<PathBuf> {
    ["pfm", "png", "exr"]
        .iter()
        .map(|ext| dir.join(format!("{name}.{ext}")))
        .find(|p| p.is_file())
        .with_context(|| {
            format!(
                "no prediction {name}.pfm, .png or .exr in {}",
                dir.display()
            )
        })
}

/// The images of a KITTI training folder with their predictions.
pub fn kitti_items(dir: &Path, predictions: Option<&Path>) -> anyhow::Result<Vec<Item>> {
    let (occ, noc) = [KittiVersion::Kitti2015, KittiVersion::Kitti2012]
        .into_iter()
        .map(|v| (dir.join(v.gt_dirs().0), dir.join(v.gt_dirs().1)))
        .find(|(o, _)| o.is_dir())
        .with_context(|| {
            format!(
                "{}: no KITTI ground truth (expected disp_occ_0 or disp_occ)",
                dir.display()
            )
        })?;
    let mut names: Vec<String> = std::fs::read_dir(&occ)
        .with_context(|| format!("cannot list {}", occ.display()))?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".png"))
        .collect();
    names.sort();
    if names.is_empty() {
        bail!("{}: no ground-truth PNGs", occ.display());
    }
    // The views are only needed when a network predicts them.
    let views = match predictions {
        Some(_) => None,
        None => Some(KittiFolder::open(dir)?),
    };
    names
        .into_iter()
        .map(|file| {
            let name = file.trim_end_matches(".png").to_string();
            let noc_map = noc.join(&file);
            let prediction = match (predictions, &views) {
                (Some(folder), _) => Prediction::File(find_prediction(folder, &name)?),
                (None, Some(views)) => Prediction::Pair {
                    reference: views.left(&name),
                    target: views.right(&name),
                    target_on_left: false,
                },
                (None, None) => bail!("{}: no predictions folder", dir.display()),
            };
            Ok(Item {
                prediction,
                gt: occ.join(&file),
                gt_factor: 1.0,
                noc: noc_map.is_file().then_some(Noc::Map(noc_map)),
                name,
            })
        })
        .collect()
}

/// The samples of a manifest with ground truth for `pair`.
pub fn manifest_items(
    path: &Path,
    (reference, target): (usize, usize),
    split: Option<Split>,
    predictions: Option<&Path>,
) -> anyhow::Result<Vec<Item>> {
    let manifest = Manifest::load(path)?;
    let items: Vec<Item> = manifest
        .samples
        .iter()
        .filter(|s| split.is_none_or(|split| s.split == split))
        .filter_map(|s| {
            let gt = s
                .ground_truth
                .iter()
                .find(|g| g.reference == reference && g.target == target)?;
            let prediction = match predictions {
                Some(folder) => find_prediction(folder, &s.id).map(Prediction::File),
                None => match (s.views.get(reference), s.views.get(target)) {
                    (Some(r), Some(t)) => Ok(Prediction::Pair {
                        reference: resolve(path, r),
                        target: resolve(path, t),
                        target_on_left: target < reference,
                    }),
                    _ => Err(anyhow::anyhow!(
                        "{}: sample {} has no view {reference} or {target}",
                        path.display(),
                        s.id
                    )),
                },
            };
            Some(prediction.map(|prediction| {
                Item {
                    name: s.id.clone(),
                    prediction,
                    gt: resolve(path, &gt.disparity),
                    gt_factor: gt.scale as f32,
                    noc: gt
                        .occlusion
                        .as_deref()
                        .map(|o| Noc::Occlusion(resolve(path, o))),
                }
            }))
        })
        .collect::<anyhow::Result<_>>()?;
    if items.is_empty() {
        bail!(
            "{}: no sample{} has ground truth for pair {reference}:{target}",
            path.display(),
            split.map_or(String::new(), |s| format!(" of the {s:?} split"))
        );
    }
    Ok(items)
}

/// Reads a prediction, or computes it with the checkpoint's network.
fn predict(
    prediction: &Prediction,
    network: Option<&CheckpointMatcher>,
) -> anyhow::Result<(FloatImage, PathBuf)> {
    match (prediction, network) {
        (Prediction::File(path), _) => Ok((read_disparity(path, None)?, path.clone())),
        (
            Prediction::Pair {
                reference,
                target,
                target_on_left,
            },
            Some(network),
        ) => {
            let reference_image = rgb::read_rgb(reference)?;
            let target_image = rgb::read_rgb(target)?;
            let disparity = if *target_on_left {
                network.predict_right(&target_image, &reference_image)?
            } else {
                network.predict(&reference_image, &target_image)?
            };
            Ok((disparity.disparity, reference.clone()))
        }
        (Prediction::Pair { reference, .. }, None) => {
            bail!("{}: no prediction and no --checkpoint", reference.display())
        }
    }
}

fn score(
    item: &Item,
    (prediction, source): &(FloatImage, PathBuf),
    gt_scale: Option<f32>,
    thresholds: &[f32],
) -> anyhow::Result<RegionSums> {
    let mut gt = read_disparity(&item.gt, gt_scale)?;
    if item.gt_factor != 1.0 {
        gt.iter_mut().for_each(|d| *d *= item.gt_factor);
    }
    let noc: Option<MaskImage> = match &item.noc {
        None => None,
        Some(Noc::Map(p)) => Some(valid_mask(&read_disparity(p, gt_scale)?)),
        Some(Noc::Mask(p)) => Some(rgb::read_mask(p)?),
        Some(Noc::Occlusion(p)) => {
            let mut mask = rgb::read_mask(p)?;
            mask.iter_mut()
                .for_each(|v| *v = if *v == 0 { 255 } else { 0 });
            Some(mask)
        }
    };
    check_size(prediction, &gt, source)?;
    Ok(evaluate(prediction, &gt, noc.as_ref(), thresholds)?)
}

fn check_size(prediction: &FloatImage, gt: &FloatImage, path: &Path) -> anyhow::Result<()> {
    if prediction.dimensions() != gt.dimensions() {
        bail!(
            "{}: prediction is {:?} but the ground truth is {:?} (width, height)",
            path.display(),
            prediction.dimensions(),
            gt.dimensions()
        );
    }
    Ok(())
}

/// Per-image sums with their per-image means and pixel-pooled totals.
pub struct Report {
    images: Vec<(String, RegionSums)>,
    pooled: RegionSums,
}

impl Report {
    /// Pools the images' sums.
    pub fn new(images: Vec<(String, RegionSums)>) -> Self {
        let mut pooled = RegionSums::default();
        for (_, sums) in &images {
            pooled.merge(sums);
        }
        Self { pooled, images }
    }

    /// Per-image mean of `region` (images without the region are left out).
    fn mean(&self, region: Region) -> Option<Metrics> {
        let mut mean = MeanMetrics::new();
        for (_, sums) in &self.images {
            if let Some(s) = sums.get(region) {
                mean.add(&s.metrics());
            }
        }
        (mean.images() > 0).then(|| mean.mean())
    }

    /// The report as JSON: per image, mean over images and pooled, per region.
    pub fn json(&self) -> Value {
        let regions = |get: &dyn Fn(Region) -> Option<Metrics>| {
            let mut map = serde_json::Map::new();
            for region in Region::EVERY {
                if let Some(m) = get(region) {
                    map.insert(region.name().into(), metrics_json(&m));
                }
            }
            Value::Object(map)
        };
        json!({
            "images": self.images.iter().map(|(name, sums)| {
                let mut v = regions(&|r| sums.get(r).map(|s| s.metrics()));
                v["name"] = json!(name);
                v
            }).collect::<Vec<_>>(),
            "mean": regions(&|r| self.mean(r)),
            "pooled": regions(&|r| self.pooled.get(r).map(|s| s.metrics())),
        })
    }

    /// The report as a text table.
    pub fn table(&self, thresholds: &[f32]) -> String {
        let count = self.images.len();
        let mean_label = format!("mean of {count} images");
        let width = self
            .images
            .iter()
            .map(|(name, _)| name.len())
            .chain([mean_label.len()])
            .max()
            .unwrap_or(0);
        let mut head = format!(
            "{:<width$} {:<4} {:>10} {:>8}",
            "image", "set", "pixels", "EPE"
        );
        for x in thresholds {
            head += &format!(" {:>8}", format!("Out-{x}"));
        }
        head += &format!(" {:>8} {:>8}\n", "D1", "density");
        let mut out = head;
        let mut row = |name: &str, region: Region, m: &Metrics, pixels: String| {
            let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}%"));
            out += &format!(
                "{:<width$} {:<4} {:>10} {:>8}",
                name,
                region.name(),
                pixels,
                m.epe.map_or("-".to_string(), |v| format!("{v:.3}"))
            );
            for &x in thresholds {
                out += &format!(" {:>8}", pct(m.out(x)));
            }
            out += &format!(" {:>8} {:>8}\n", pct(m.d1), pct(m.density));
        };
        for (name, sums) in &self.images {
            for region in Region::EVERY {
                if let Some(s) = sums.get(region) {
                    let m = s.metrics();
                    row(name, region, &m, m.pixels.to_string());
                }
            }
        }
        for region in Region::EVERY {
            if let Some(m) = self.mean(region) {
                row(&mean_label, region, &m, "-".into());
            }
        }
        for region in Region::EVERY {
            if let Some(s) = self.pooled.get(region) {
                let m = s.metrics();
                row("pooled", region, &m, m.pixels.to_string());
            }
        }
        out
    }
}

fn metrics_json(m: &Metrics) -> Value {
    let mut v = json!({
        "pixels": m.pixels,
        "epe": m.epe,
        "d1": m.d1,
        "density": m.density,
    });
    for &(x, value) in &m.out {
        v[format!("out{x}")] = json!(value);
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_parse_by_their_manifest_names() {
        assert_eq!(parse_split("train"), Ok(Split::Train));
        assert_eq!(parse_split("val"), Ok(Split::Val));
        assert_eq!(parse_split("test"), Ok(Split::Test));
        assert_eq!(
            parse_split("Test"),
            Err("`Test` is not a split: train, val or test".into())
        );
    }
}
