//! `mbs-tool extrapolate`: a stereo pair -> two extra views, one baseline
//! further left and one further right (SPEC §4), for one pair or a whole
//! KITTI folder.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail, ensure};
use clap::{Parser, ValueEnum};
use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_core::formats::read_float_map;
use mbs_core::formats::rgb::{read_rgb, write_mask_png, write_rgb_png};
use mbs_core::{FloatImage, RgbImage, Side};
use mbs_dataset::kitti::KittiFolder;
use mbs_infer::inpaint::{BackgroundFill, Inpainter, IsotropicFill};
use mbs_infer::onnx::{ModelCard, OnnxInpainter, OnnxStereo};
use mbs_infer::{Sgm, SgmConfig, StereoMatcher, estimate_max_disparity};
use mbs_warp::{Dilation, extrapolate_view, fill_disparity_background, forward_warp};

use crate::cli::batch::{self, Outcome};
use crate::cli::onnx::OnnxArgs;
use crate::cli::shard::Shard;

mod manifest;
mod preview;

/// Arguments of `extrapolate`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool extrapolate --left L.png --right R.png --left-disparity DL.pfm --out out/
  mbs-tool extrapolate --kitti kitti2015/training --left-disparity-dir kitti2015/training/disp_occ_0
  mbs-tool extrapolate --kitti kitti2015/testing --disparity onnx:igev.onnx --card igev \\
      --inpaint onnx:lama_fp32.onnx --inpaint-card lama --device cuda

Outputs: image_1 (new view left of the left view, at -B) and image_4 (right of
the right view, at +2B), mask_1 / mask_4 (255 = synthesised: holes and
dilated pixels) and the disparities used, disparity_2 (left view) and
disparity_3 (right view) as PFM. One pair: OUT/image_1.png, OUT/mask_1.png,
OUT/disparity_2.pfm... KITTI: sibling folders image_1/, image_4/, mask_1/,
mask_4/, disparity_2/, disparity_3/ beside image_2/ and image_3/, one file per
frame. Disparity files may be PFM, EXR or KITTI 16-bit PNG (value / 256,
0 = invalid); invalid pixels are filled from the background side. With only
one view's disparity, the other is derived by warping it (z-buffer) and
filling the disocclusions from the background side. Finished frames are
skipped, so an interrupted run resumes where it stopped.")]
pub struct Args {
    /// Left view of one pair (image_2 in KITTI).
    #[arg(long, requires = "right", required_unless_present = "kitti")]
    pub left: Option<PathBuf>,
    /// Right view of one pair (image_3 in KITTI).
    #[arg(long, requires = "left")]
    pub right: Option<PathBuf>,
    /// A KITTI split folder holding image_2/ and image_3/ (e.g. kitti2015/training).
    #[arg(long, conflicts_with_all = ["left", "left_disparity", "right_disparity"])]
    pub kitti: Option<PathBuf>,
    /// Output folder [required for one pair; KITTI: default the --kitti folder].
    #[arg(long, required_unless_present = "kitti")]
    pub out: Option<PathBuf>,
    /// Disparity of the left view (one pair).
    #[arg(long)]
    pub left_disparity: Option<PathBuf>,
    /// Disparity of the right view (one pair).
    #[arg(long)]
    pub right_disparity: Option<PathBuf>,
    /// Folder of disparities as this command writes them: one pair,
    /// disparity_2.* and/or disparity_3.*; KITTI, disparity_2/ and/or disparity_3/.
    #[arg(long, conflicts_with_all = ["left_disparity", "right_disparity"])]
    pub disparity_dir: Option<PathBuf>,
    /// KITTI: folder of left-view disparities named like image_2's files (e.g. disp_occ_0).
    #[arg(long, requires = "kitti", conflicts_with = "disparity_dir")]
    pub left_disparity_dir: Option<PathBuf>,
    /// KITTI: folder of right-view disparities named like image_3's files.
    #[arg(long, requires = "kitti", conflicts_with = "disparity_dir")]
    pub right_disparity_dir: Option<PathBuf>,
    /// Where disparities come from when no file is given for a frame: `sgm`
    /// (the built-in semi-global matcher) or `onnx:MODEL.onnx` (a stereo
    /// network fed as --card says); left view, and right view by mirroring.
    #[arg(long, value_name = "sgm|onnx:MODEL", value_parser = parse_disparity_source)]
    pub disparity: Option<DisparitySource>,
    /// How to feed `--disparity onnx:MODEL`: a built-in card name or a card FILE.json.
    #[arg(long, value_name = "NAME|FILE.json")]
    pub card: Option<String>,
    /// Number of disparities the matcher searches (0 = estimate per pair, up to 256).
    #[arg(long, default_value_t = 0)]
    pub max_disparity: u32,
    /// How the hole masks are grown before inpainting (none measured best on
    /// Middlebury Tsukuba, also with disparities that bleed across edges).
    #[arg(long, value_enum, default_value_t = DilationKind::None)]
    pub dilation: DilationKind,
    /// Radius in pixels of the dilation.
    #[arg(long, default_value_t = 2)]
    pub dilate_radius: u32,
    /// Inpainting of the masked pixels: `background` (fill each hole from
    /// its background side, guided by the warped disparity), `isotropic`
    /// (from the whole rim inwards, Telea-like) or `onnx:MODEL.onnx` (an
    /// inpainting network such as LaMa or MI-GAN, fed as --inpaint-card says).
    #[arg(long, value_name = "background|isotropic|onnx:MODEL", default_value = "background", value_parser = parse_inpaint)]
    pub inpaint: InpaintKind,
    /// How to feed `--inpaint onnx:MODEL`: a built-in card name (lama, migan) or a card FILE.json.
    #[arg(long, value_name = "NAME|FILE.json")]
    pub inpaint_card: Option<String>,
    /// ONNX Runtime settings (with onnx:MODEL sources).
    #[command(flatten)]
    pub onnx: OnnxArgs,
    /// Also write a contact sheet per frame (preview/NAME.png): the four
    /// views, synthesised pixels tinted red, and the disparities used.
    #[arg(long)]
    pub preview: bool,
    /// Focal length in pixels, recorded in the manifest's rig (KITTI: about 721).
    #[arg(long, default_value_t = 721.5377)]
    pub focal: f64,
    /// Baseline between the two input cameras in metres, recorded in the manifest (KITTI: 0.54).
    #[arg(long, default_value_t = 0.54)]
    pub baseline: f64,
    /// Process only shard K of N (0-based); run once more without it to write the manifest.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,
    /// Worker threads (0 = one per core).
    #[arg(long, default_value_t = 0)]
    pub jobs: usize,
}

/// Disparity estimators for frames without disparity files.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DisparitySource {
    /// The built-in semi-global matcher (`mbs-tool predict`).
    Sgm,
    /// An ONNX stereo network (`onnx:MODEL.onnx`).
    Onnx(PathBuf),
}

fn parse_disparity_source(s: &str) -> Result<DisparitySource, String> {
    match (s, s.strip_prefix("onnx:")) {
        ("sgm", _) => Ok(DisparitySource::Sgm),
        (_, Some(model)) if !model.is_empty() => Ok(DisparitySource::Onnx(model.into())),
        _ => Err(format!(
            "invalid disparity source {s:?}: expected sgm or onnx:MODEL.onnx"
        )),
    }
}

/// Mask dilations (see `mbs_warp::Dilation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DilationKind {
    /// Inpaint the holes only.
    None,
    /// A square of side 2r + 1.
    Square,
    /// A disc of radius r.
    Ellipse,
    /// Grow holes at depth edges by r pixels into the background.
    BackgroundSide,
    /// Grow holes at depth edges by r pixels into the foreground.
    ForegroundSide,
}

/// Inpainters: the built-ins (see `mbs_infer::inpaint`) or an ONNX network.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum InpaintKind {
    /// Fill each hole from its background side, guided by the warped disparity.
    Background,
    /// Fill holes from their whole rim inwards (Telea-like).
    Isotropic,
    /// An ONNX inpainting network (`onnx:MODEL.onnx`).
    Onnx(PathBuf),
}

fn parse_inpaint(s: &str) -> Result<InpaintKind, String> {
    match (s, s.strip_prefix("onnx:")) {
        ("background", _) => Ok(InpaintKind::Background),
        ("isotropic", _) => Ok(InpaintKind::Isotropic),
        (_, Some(model)) if !model.is_empty() => Ok(InpaintKind::Onnx(model.into())),
        _ => Err(format!(
            "invalid inpainter {s:?}: expected background, isotropic or onnx:MODEL.onnx"
        )),
    }
}

/// Where disparities come from for frames without files.
enum Matcher {
    /// The built-in semi-global matcher, built per frame.
    Sgm,
    /// An ONNX stereo network.
    Onnx(Box<OnnxStereo>),
}

/// The input and output files of one frame.
struct Frame {
    name: String,
    left: PathBuf,
    right: PathBuf,
    left_disparity: Option<PathBuf>,
    right_disparity: Option<PathBuf>,
    image_1: PathBuf,
    image_4: PathBuf,
    mask_1: PathBuf,
    mask_4: PathBuf,
    disparity_2: PathBuf,
    disparity_3: PathBuf,
    preview: PathBuf,
    /// KITTI ground truth of the left view, recorded in the manifest.
    ground_truth: Option<PathBuf>,
}

impl Frame {
    fn outputs(&self) -> [&PathBuf; 6] {
        [
            &self.image_1,
            &self.image_4,
            &self.mask_1,
            &self.mask_4,
            &self.disparity_2,
            &self.disparity_3,
        ]
    }
}

/// What every frame is processed with.
struct Settings {
    dilation: Dilation,
    inpainter: Box<dyn Inpainter>,
    matcher: Option<Matcher>,
    max_disparity: u32,
    preview: bool,
}

/// Runs `extrapolate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    crate::cli::set_threads(args.jobs)?;
    let r = args.dilate_radius;
    let settings = Settings {
        dilation: match args.dilation {
            DilationKind::None => Dilation::None,
            DilationKind::Square => Dilation::Square(r),
            DilationKind::Ellipse => Dilation::Ellipse(r),
            DilationKind::BackgroundSide => Dilation::BackgroundSide(r),
            DilationKind::ForegroundSide => Dilation::ForegroundSide(r),
        },
        inpainter: match &args.inpaint {
            InpaintKind::Background => Box::new(BackgroundFill::default()),
            InpaintKind::Isotropic => Box::new(IsotropicFill),
            InpaintKind::Onnx(model) => {
                let card = args
                    .inpaint_card
                    .as_deref()
                    .context("--inpaint onnx:MODEL needs --inpaint-card NAME|FILE.json")?;
                let net = OnnxInpainter::open(model, ModelCard::load(card)?, &args.onnx.options())?;
                args.onnx
                    .report_fallback(&model.display().to_string(), net.device());
                Box::new(net)
            }
        },
        matcher: match &args.disparity {
            None => None,
            Some(DisparitySource::Sgm) => Some(Matcher::Sgm),
            Some(DisparitySource::Onnx(model)) => {
                let card = args
                    .card
                    .as_deref()
                    .context("--disparity onnx:MODEL needs --card NAME|FILE.json")?;
                let net = OnnxStereo::open(model, ModelCard::load(card)?, &args.onnx.options())?;
                args.onnx
                    .report_fallback(&model.display().to_string(), net.device());
                Some(Matcher::Onnx(Box::new(net)))
            }
        },
        max_disparity: args.max_disparity,
        preview: args.preview,
    };
    let (frames, out) = match &args.kitti {
        Some(root) => (
            kitti_frames(root, &args)?,
            args.out.clone().unwrap_or_else(|| root.clone()),
        ),
        None => (
            vec![pair_frame(&args)?],
            args.out.clone().unwrap_or_default(),
        ),
    };
    let selected: Vec<&Frame> = match args.shard {
        Some(shard) => shard.select(frames.iter().collect()),
        None => frames.iter().collect(),
    };
    let summary = batch::run(
        &selected,
        "frames",
        |f| f.name.clone(),
        |f| process(f, &settings),
    );
    let result = summary.finish("extrapolate", "frames");
    if args.shard.is_none() {
        let manifest =
            manifest::four_view_manifest(&frames_done(&frames), &out, args.focal, args.baseline)?;
        let path = out.join("manifest.json");
        manifest.save(&path)?;
        eprintln!(
            "extrapolate: {} four-view samples -> {}",
            manifest.samples.len(),
            path.display()
        );
    }
    result
}

/// The frames whose outputs are all written, as manifest entries.
fn frames_done(frames: &[Frame]) -> Vec<manifest::FourViews<'_>> {
    frames
        .iter()
        .filter(|f| f.outputs().iter().all(|p| p.exists()))
        .map(|f| manifest::FourViews {
            id: f.name.trim_end_matches(".png"),
            views: [&f.image_1, &f.left, &f.right, &f.image_4],
            masks: [&f.mask_1, &f.mask_4],
            ground_truth: f.ground_truth.as_deref(),
        })
        .collect()
}

/// The one frame of `--left/--right` mode.
fn pair_frame(args: &Args) -> anyhow::Result<Frame> {
    let (Some(left), Some(right), Some(out)) = (&args.left, &args.right, &args.out) else {
        bail!("give --left, --right and --out, or --kitti");
    };
    let (left_disparity, right_disparity) = match &args.disparity_dir {
        Some(dir) => (find_map(dir, "disparity_2"), find_map(dir, "disparity_3")),
        None => (args.left_disparity.clone(), args.right_disparity.clone()),
    };
    if let Some(dir) = &args.disparity_dir {
        ensure!(
            left_disparity.is_some() || right_disparity.is_some(),
            "{}: no disparity_2 or disparity_3 file (.pfm, .exr or .png) in this folder",
            dir.display()
        );
    }
    Ok(Frame {
        name: left.display().to_string(),
        left: left.clone(),
        right: right.clone(),
        left_disparity,
        right_disparity,
        image_1: out.join("image_1.png"),
        image_4: out.join("image_4.png"),
        mask_1: out.join("mask_1.png"),
        mask_4: out.join("mask_4.png"),
        disparity_2: out.join("disparity_2.pfm"),
        disparity_3: out.join("disparity_3.pfm"),
        preview: out.join("preview.png"),
        ground_truth: None,
    })
}

/// The frames of a KITTI split folder (2015 or 2012, training or testing):
/// every left view with its namesake on the right.
fn kitti_frames(root: &Path, args: &Args) -> anyhow::Result<Vec<Frame>> {
    let folder = KittiFolder::open(root)?;
    let out = args.out.as_deref().unwrap_or(root);
    let (left_disp_dir, right_disp_dir) = match &args.disparity_dir {
        Some(dir) => (Some(dir.join("disparity_2")), Some(dir.join("disparity_3"))),
        None => (
            args.left_disparity_dir.clone(),
            args.right_disparity_dir.clone(),
        ),
    };
    Ok(folder
        .frames
        .iter()
        .map(|stem| {
            let name = format!("{stem}.png");
            Frame {
                left: folder.left(stem),
                right: folder.right(stem),
                left_disparity: left_disp_dir.as_deref().and_then(|d| find_map(d, stem)),
                right_disparity: right_disp_dir.as_deref().and_then(|d| find_map(d, stem)),
                image_1: out.join("image_1").join(&name),
                image_4: out.join("image_4").join(&name),
                mask_1: out.join("mask_1").join(&name),
                mask_4: out.join("mask_4").join(&name),
                disparity_2: out.join("disparity_2").join(format!("{stem}.pfm")),
                disparity_3: out.join("disparity_3").join(format!("{stem}.pfm")),
                preview: out.join("preview").join(&name),
                ground_truth: folder.disparity_occ(stem),
                name,
            }
        })
        .collect())
}

/// `dir/stem.pfm`, `.exr` or `.png`, the first that exists.
fn find_map(dir: &Path, stem: &str) -> Option<PathBuf> {
    ["pfm", "exr", "png"]
        .iter()
        .map(|ext| dir.join(format!("{stem}.{ext}")))
        .find(|p| p.is_file())
}

/// Extrapolates one frame, unless all its outputs exist.
fn process(frame: &Frame, settings: &Settings) -> anyhow::Result<Outcome> {
    if frame.outputs().iter().all(|p| p.exists()) && (!settings.preview || frame.preview.exists()) {
        return Ok(Outcome::Skipped);
    }
    let left = read_rgb(&frame.left)?;
    let right = read_rgb(&frame.right)?;
    ensure!(
        left.dimensions() == right.dimensions(),
        "{} is {:?} but {} is {:?} (width, height): not a rectified pair",
        frame.left.display(),
        left.dimensions(),
        frame.right.display(),
        right.dimensions()
    );
    let (disp_left, disp_right) = disparities(frame, &left, &right, settings)?;
    let views = [
        (&left, &disp_left, Side::Left, &frame.image_1, &frame.mask_1),
        (
            &right,
            &disp_right,
            Side::Right,
            &frame.image_4,
            &frame.mask_4,
        ),
    ];
    let mut new_views = Vec::with_capacity(2);
    for (image, disparity, side, image_path, mask_path) in views {
        let view = extrapolate_view(image, disparity, side, settings.dilation)?;
        let filled = settings
            .inpainter
            .inpaint(&view.image, &view.mask, Some(&view.disparity))
            .with_context(|| format!("inpainting {}", image_path.display()))?;
        write_mask_png(mask_path, &view.mask)?;
        write_rgb_png(image_path, &filled)?;
        new_views.push((filled, view.mask));
    }
    if settings.preview {
        let sheet = preview::contact_sheet(
            [&new_views[0].0, &left, &right, &new_views[1].0],
            [&new_views[0].1, &new_views[1].1],
            [&disp_left, &disp_right],
        );
        write_rgb_png(&frame.preview, &sheet)?;
    }
    write_pfm_grey(&frame.disparity_2, &disp_left, Endian::Little)?;
    write_pfm_grey(&frame.disparity_3, &disp_right, Endian::Little)?;
    Ok(Outcome::Done)
}

/// The disparities of both views: read, or derived from the other view's.
fn disparities(
    frame: &Frame,
    left: &RgbImage,
    right: &RgbImage,
    settings: &Settings,
) -> anyhow::Result<(FloatImage, FloatImage)> {
    let load = |path: &Path| -> anyhow::Result<FloatImage> {
        let map = read_float_map(path)?;
        let bad = map.iter().filter(|d| d.is_nan() || **d < 0.0).count();
        ensure!(
            bad == 0,
            "{}: {bad} NaN or negative disparities (disparity is a non-negative magnitude; mark invalid pixels +inf or 0 in PNGs)",
            path.display()
        );
        ensure!(
            map.dimensions() == left.dimensions(),
            "{}: disparity is {:?} but the views are {:?} (width, height)",
            path.display(),
            map.dimensions(),
            left.dimensions()
        );
        ensure!(
            map.iter().any(|d| d.is_finite()),
            "{}: no valid disparity at all",
            path.display()
        );
        Ok(fill_disparity_background(&map))
    };
    // The other view's disparity: warp this one there, fill the disocclusions.
    let derive = |view: &RgbImage, disparity: &FloatImage, side: Side| {
        forward_warp(view, disparity, side).map(|w| fill_disparity_background(&w.disparity))
    };
    Ok(match (&frame.left_disparity, &frame.right_disparity) {
        (Some(l), Some(r)) => (load(l)?, load(r)?),
        (Some(l), None) => {
            let dl = load(l)?;
            let dr = derive(left, &dl, Side::Right)?;
            (dl, dr)
        }
        (None, Some(r)) => {
            let dr = load(r)?;
            let dl = derive(right, &dr, Side::Left)?;
            (dl, dr)
        }
        (None, None) if settings.matcher.is_some() => {
            let sgm;
            let matcher: &dyn StereoMatcher = match &settings.matcher {
                Some(Matcher::Onnx(net)) => net.as_ref(),
                _ => {
                    let max_disparity = match settings.max_disparity {
                        0 => estimate_max_disparity(left, right, 256)?,
                        n => n,
                    };
                    sgm = Sgm::new(SgmConfig::with_max_disparity(max_disparity));
                    &sgm
                }
            };
            let dl = matcher.predict(left, right)?.disparity;
            let dr = matcher.predict_right(left, right)?.disparity;
            (
                fill_disparity_background(&dl),
                fill_disparity_background(&dr),
            )
        }
        (None, None) => bail!(
            "no disparity for {}: give --left-disparity and/or --right-disparity \
             (KITTI: --left-disparity-dir / --right-disparity-dir), --disparity-dir, or --disparity sgm|onnx:MODEL",
            frame.left.display()
        ),
    })
}
