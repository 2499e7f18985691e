//! `mbs-tool mono`: single photos -> multi-baseline sets through a
//! monocular depth network (or depth files), for S3 training.

use std::path::{Path, PathBuf};

use anyhow::bail;
use clap::{Parser, ValueEnum};
use mbs_core::inputs::InputFiles;
use mbs_dataset::Split;
use mbs_dataset::manifest::Provenance;
use mbs_dataset::photos::PhotoSource;
use mbs_extrapolate::mono::{Scaling, ViewLayout};
use mbs_extrapolate::photo_set::{DepthSource, PhotoSet, photo_sets};
use mbs_extrapolate::{Extrapolator, SetKind, views_manifest};
use mbs_infer::DepthKind;
use mbs_infer::onnx::{ModelCard, OnnxDepth};

use crate::cli::batch::{self, Outcome};
use crate::cli::onnx::OnnxArgs;
use crate::cli::synthesis::SynthesisArgs;

/// The manifest of the sets, in the output folder.
const MANIFEST_FILE: &str = "manifest.json";

/// The rig recorded when no --focal/--baseline is given: KITTI's, as
/// `extrapolate` records.
const NOMINAL_FOCAL_PX: f64 = 721.5377;
/// See [`NOMINAL_FOCAL_PX`].
const NOMINAL_BASELINE_M: f64 = 0.54;

/// Arguments of `mono`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool mono --images photos/ --model depth_anything_v2_vits_dynamic.onnx \\
      --card depth-anything-v2-small --out sets/
  mbs-tool mono --image street.jpg --model fastdepth_7.onnx --card fastdepth --preview --out set/
  mbs-tool mono --list train.txt --model midas.onnx --card midas-v21-small --views 5 \\
      --reference 2 --max-disparity 0.04:0.12 --seed 3 --out sets/
  mbs-tool mono --images photos/ --depth-dir depths/ --depth-kind metric-depth \\
      --scale metric --focal 720 --baseline 0.5 --out sets/
  mbs-tool mono --manifest kitti/manifest.json --camera 1 --model m.onnx --card c.json --out sets/

Each photo becomes a set of --views cameras one baseline apart, the photo at
camera --reference (default: 4 cameras, the photo at the second, as the
paper's sets: one further left, the photo, its right partner, one further
right). The depth map (a network's, through ONNX Runtime as its card says,
or a file) becomes the disparity of one baseline: --scale range (default for
depth and relative maps) takes it as inverse depth, shifted to start at 0
if it has negative values, and scales it so its largest value is a fraction of the width drawn per photo
in --max-disparity from --seed and the photo's id (Watson et al.'s rule, so
the network sees many rigs; the default 0.05:0.15 of the width is about what
one baseline of KITTI or MBS20K shows, and the outer views of 4 reach 0.3);
--scale metric gives f*B/Z from metric depth with --focal and --baseline;
--scale as-is (default for disparity maps) keeps a disparity in pixels.
Every other camera is the photo forward-warped by that disparity times its
distance in baselines, its holes masked (and dilated) and inpainted exactly
as extrapolate does.

Outputs, sibling folders under OUT, one file per photo named by its id (the
file stem, or the path under --images without extension): image_K/ID.png
for each synthesised camera K, mask_K/ID.png (255 = synthesised), the photo
linked (or copied) as image_R/ID.EXT, disparity_R/ID.pfm (one baseline),
preview/ID.png with --preview, and OUT/manifest.json naming the model, the
card, the scaling and the seed. The same inputs and seed give the same bytes.
A photo that cannot be used (grey, 16-bit, a depth map with NaN...) is
reported and the others go on; the exit status is then non-zero. Finished
photos are skipped, so an interrupted run resumes where it stopped (with the
same settings: a run with others into the same OUT is refused); nothing is
written outside OUT, and no output replaces an input.")]
pub struct Args {
    /// One photo.
    #[arg(long, group = "photos", value_name = "FILE")]
    pub image: Option<PathBuf>,
    /// A folder of photos (.png, .jpg, .ppm..., walked in path order).
    #[arg(long, group = "photos", value_name = "DIR")]
    pub images: Option<PathBuf>,
    /// A list file: one photo path a line, relative to the list's folder.
    #[arg(long, group = "photos", value_name = "FILE")]
    pub list: Option<PathBuf>,
    /// A manifest whose views of camera --camera are the photos.
    #[arg(long, group = "photos", value_name = "FILE")]
    pub manifest: Option<PathBuf>,
    /// With --manifest: the camera whose views are the photos.
    #[arg(long, default_value_t = 0, requires = "manifest")]
    pub camera: usize,
    /// With --manifest: only samples of this split (train, val, test).
    #[arg(long, requires = "manifest", value_parser = crate::cli::pairs::parse_split)]
    pub split: Option<Split>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// A monocular depth network (ONNX), fed as --card says.
    #[arg(
        long,
        value_name = "FILE.onnx",
        group = "depth_source",
        requires = "card"
    )]
    pub model: Option<PathBuf>,
    /// The depth network's card: a built-in name (fastdepth,
    /// depth-anything-v2-small...) or a card FILE.json.
    #[arg(long, value_name = "NAME|FILE.json", requires = "model")]
    pub card: Option<String>,
    /// The photo's depth map (with --image): PFM, EXR or 16-bit PNG.
    #[arg(long, value_name = "FILE", group = "depth_source", requires = "image")]
    pub depth: Option<PathBuf>,
    /// A folder of depth maps named by photo id (ID.pfm, ID.exr, ID.png).
    #[arg(long, value_name = "DIR", group = "depth_source")]
    pub depth_dir: Option<PathBuf>,
    /// What the depth files hold: metric-depth (metres),
    /// inverse-relative (a relative model's output) or disparity (pixels).
    #[arg(long, value_name = "KIND", value_parser = clap::value_parser!(DepthKind))]
    pub depth_kind: Option<DepthKind>,
    /// Cameras per set.
    #[arg(long, default_value_t = 4, value_parser = crate::cli::values::views)]
    pub views: usize,
    /// The photo's camera, 0-based.
    #[arg(long, default_value_t = 1)]
    pub reference: usize,
    /// How the depth becomes a disparity [default: as-is for disparity
    /// maps, range otherwise].
    #[arg(long, value_enum)]
    pub scale: Option<ScaleKind>,
    /// --scale range: the largest disparity of one baseline, as a fraction
    /// of the width, drawn per photo between LOW and HIGH.
    #[arg(long, value_name = "LOW:HIGH", default_value = "0.05:0.15", value_parser = crate::cli::values::fraction_range)]
    pub max_disparity: (f32, f32),
    /// --scale range: the seed of the per-photo draws.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Focal length in pixels: the rig's (and f in f*B/Z with --scale
    /// metric) [default: 721.5377, recorded as nominal].
    #[arg(long, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub focal: Option<f64>,
    /// Baseline between adjacent cameras in metres: the rig's (and B in
    /// f*B/Z with --scale metric) [default: 0.54, recorded as nominal].
    #[arg(long, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub baseline: Option<f64>,
    /// How views are synthesised.
    #[command(flatten)]
    pub synthesis: SynthesisArgs,
    /// Also write a contact sheet per photo (preview/ID.png): every view,
    /// synthesised pixels tinted red, and the disparity used.
    #[arg(long)]
    pub preview: bool,
    /// Where the networks run.
    #[command(flatten)]
    pub runtime: OnnxArgs,
    /// Sharding and worker threads.
    #[command(flatten)]
    pub batch: crate::cli::flags::Batch,
}

/// `--scale`: how a depth map becomes a disparity (see
/// `mbs_extrapolate::mono::Scaling`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ScaleKind {
    /// The largest disparity drawn per photo in --max-disparity.
    Range,
    /// f*B/Z from metric depth.
    Metric,
    /// The map is a disparity in pixels.
    AsIs,
}

/// Runs `mono`.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.batch.threads.start()?;
    let layout = ViewLayout::new(args.views, args.reference).map_err(anyhow::Error::msg)?;
    let photos = photo_source(&args)?.photos()?;
    // Models are opened before anything is written, so a bad model leaves
    // no output folder behind.
    let network = depth_network(&args)?;
    let kind = match (&network, args.depth_kind) {
        (Some(network), _) => network.card().output.kind.unwrap_or(DepthKind::MetricDepth),
        (None, Some(kind)) => kind,
        (None, None) => bail!(
            "--depth and --depth-dir need --depth-kind metric-depth|inverse-relative|disparity"
        ),
    };
    let scaling = scaling(&args, kind)?;
    let extrapolator = Extrapolator::new(
        args.synthesis.dilation(),
        args.synthesis.inpainter(&args.runtime)?,
    );
    let depth = match &network {
        Some(network) => DepthSource::Network(network),
        None => DepthSource::Files(kind),
    };
    let sets = photo_sets(
        &photos,
        &args.out,
        layout,
        args.depth_dir.as_deref(),
        args.depth.as_deref(),
    );
    let selected: Vec<&PhotoSet> = match args.batch.shard {
        Some(shard) => shard.select(sets.iter().collect()),
        None => sets.iter().collect(),
    };
    let (inputs, outputs) = files(&args, &sets, &selected);
    let settings = settings(&args, network.as_ref(), scaling, kind)?;
    let _out = crate::cli::take_out_settled(
        &args.out,
        args.batch.shard,
        "mono",
        (&inputs, &outputs),
        &settings,
        false,
    )?;
    let summary = batch::run(
        &selected,
        "photos",
        |set| set.name.clone(),
        |set| {
            if set.is_done(args.preview) {
                return Ok(Outcome::Skipped);
            }
            set.process(&extrapolator, &depth, scaling, args.preview)?;
            Ok(Outcome::Done)
        },
    );
    let result = summary.finish("mono", "photos");
    if args.batch.shard.is_none() {
        write_manifest(&args, &sets, settings)?;
    }
    result
}

/// Where the photos come from.
fn photo_source(args: &Args) -> anyhow::Result<PhotoSource> {
    Ok(
        match (&args.image, &args.images, &args.list, &args.manifest) {
            (Some(file), ..) => {
                crate::cli::require_file(file, "photo")?;
                PhotoSource::File(file.clone())
            }
            (_, Some(dir), ..) => PhotoSource::Folder {
                dir: dir.clone(),
                skip: Some(args.out.clone()),
            },
            (_, _, Some(list), _) => PhotoSource::List(list.clone()),
            (.., Some(manifest)) => PhotoSource::Manifest {
                path: manifest.clone(),
                camera: args.camera,
                split: args.split,
            },
            _ => {
                bail!("give the photos: --image FILE, --images DIR, --list FILE or --manifest FILE")
            }
        },
    )
}

/// The depth network of --model and --card, if given (a card of another
/// task is refused when it is opened).
fn depth_network(args: &Args) -> anyhow::Result<Option<OnnxDepth>> {
    let (Some(model), Some(card)) = (&args.model, &args.card) else {
        if args.depth.is_none() && args.depth_dir.is_none() {
            bail!("give the depth: --model FILE.onnx --card NAME, --depth FILE or --depth-dir DIR");
        }
        return Ok(None);
    };
    if args.depth_kind.is_some() {
        bail!("--depth-kind is for depth files; a network's card says what its output is");
    }
    let network = OnnxDepth::open(model, ModelCard::load(card)?, &args.runtime.options()?)?;
    args.runtime
        .report_fallback(&model.display().to_string(), network.device());
    Ok(Some(network))
}

/// The scaling --scale asks for (or the default for maps of `kind`).
fn scaling(args: &Args, kind: DepthKind) -> anyhow::Result<Scaling> {
    let scale = args.scale.unwrap_or(match kind {
        DepthKind::Disparity => ScaleKind::AsIs,
        _ => ScaleKind::Range,
    });
    Ok(match scale {
        ScaleKind::Range => Scaling::Range {
            low: args.max_disparity.0,
            high: args.max_disparity.1,
            seed: args.seed,
        },
        ScaleKind::Metric => {
            let (Some(focal_px), Some(baseline_m)) = (args.focal, args.baseline) else {
                bail!("--scale metric needs --focal PX and --baseline M (the virtual rig's)");
            };
            if kind != DepthKind::MetricDepth {
                bail!("--scale metric needs metric depth, but the depth is {kind}");
            }
            Scaling::Metric {
                focal_px,
                baseline_m,
            }
        }
        ScaleKind::AsIs if kind != DepthKind::Disparity => {
            bail!("--scale as-is needs a disparity, but the depth is {kind}")
        }
        ScaleKind::AsIs => Scaling::AsIs,
    })
}

/// Every file the sets are read from (photos, depth files, models,
/// cards), and every file the `selected` ones are written to (with the
/// manifest, unless sharded).
fn files(args: &Args, sets: &[PhotoSet], selected: &[&PhotoSet]) -> (InputFiles, Vec<PathBuf>) {
    let mut inputs = InputFiles::new();
    inputs.extend(sets.iter().flat_map(PhotoSet::inputs));
    let card = args.card.as_ref().map(PathBuf::from);
    inputs.extend(
        [&args.model, &card, &args.manifest, &args.list]
            .into_iter()
            .flatten(),
    );
    inputs.extend(args.synthesis.model_file());
    let mut outputs: Vec<PathBuf> = selected
        .iter()
        .flat_map(|set| set.written(args.preview))
        .map(Path::to_path_buf)
        .collect();
    if args.batch.shard.is_none() {
        outputs.push(args.out.join(MANIFEST_FILE));
    }
    (inputs, outputs)
}

/// The settings the sets' files are made with: the depth (model file
/// name, its sha256 and card, or the files' kind), the scaling, the
/// cameras and the synthesis. A rerun into the same folder must repeat
/// them, and the manifest's provenance records them.
fn settings(
    args: &Args,
    network: Option<&OnnxDepth>,
    scaling: Scaling,
    kind: DepthKind,
) -> anyhow::Result<serde_json::Value> {
    let depth = match (&args.model, network) {
        (Some(model), Some(network)) => serde_json::json!({
            "model": model.file_name().map(|n| n.to_string_lossy()),
            "model_sha256": mbs_dataset::checksum::sha256_file(model)?,
            "card": network.card(),
            "kind": kind,
        }),
        _ => serde_json::json!({ "files": true, "kind": kind }),
    };
    let scaling = match scaling {
        Scaling::Range { low, high, seed } => serde_json::json!({
            "mode": "range",
            "max_disparity": [low, high],
            "unit": "fraction of the width, one baseline",
            "seed": seed,
            "draw": "uniform per photo from the seed and the photo's id (ChaCha8)",
        }),
        Scaling::Metric {
            focal_px,
            baseline_m,
        } => {
            serde_json::json!({ "mode": "metric", "focal_px": focal_px, "baseline_m": baseline_m })
        }
        Scaling::AsIs => serde_json::json!({ "mode": "as-is" }),
    };
    Ok(serde_json::json!({
        "depth": depth,
        "scaling": scaling,
        "views": args.views,
        "reference": args.reference,
        "synthesis": args.synthesis.provenance(),
    }))
}

/// What the manifest records of how the sets were made: the `settings`,
/// where the depth files were, and whether the rig is nominal.
fn provenance(args: &Args, mut settings: serde_json::Value) -> Provenance {
    let nominal = args.focal.is_none() || args.baseline.is_none();
    settings["rig"] = serde_json::json!(if nominal { "nominal" } else { "given" });
    if let Some(files) = args.depth.as_ref().or(args.depth_dir.as_ref()) {
        settings["depth"]["files"] = serde_json::json!(files);
    }
    Provenance {
        tool: "mbs-tool mono".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        settings,
    }
}

/// Writes `OUT/manifest.json`, the complete sets (none: nothing is
/// written, and it is said).
fn write_manifest(
    args: &Args,
    sets: &[PhotoSet],
    settings: serde_json::Value,
) -> anyhow::Result<()> {
    let done: Vec<_> = sets
        .iter()
        .filter(|set| set.is_done(false))
        .map(PhotoSet::files)
        .collect();
    if done.is_empty() {
        eprintln!("mono: no set is complete, so no manifest was written");
        return Ok(());
    }
    let set_kind = SetKind {
        name: "mono",
        focal: args.focal.unwrap_or(NOMINAL_FOCAL_PX),
        baseline: args.baseline.unwrap_or(NOMINAL_BASELINE_M),
        provenance: provenance(args, settings),
    };
    let manifest = views_manifest(&done, &args.out, set_kind)?;
    let path = args.out.join(MANIFEST_FILE);
    manifest.save(&path)?;
    eprintln!(
        "mono: {} sets of {} views -> {}",
        manifest.samples.len(),
        args.views,
        path.display()
    );
    Ok(())
}
