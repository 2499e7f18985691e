//! The flags of view synthesis, shared by the commands that synthesise
//! views (`extrapolate`, `mono`): how hole masks grow and what fills them.

use std::path::PathBuf;

use anyhow::Context;
use clap::ValueEnum;
use mbs_infer::inpaint::{BackgroundFill, Inpainter, IsotropicFill};
use mbs_infer::onnx::{ModelCard, OnnxInpainter};
use mbs_warp::Dilation;

use crate::cli::onnx::OnnxArgs;

/// `--dilation`, `--dilate-radius`, `--inpaint` and `--inpaint-card`.
#[derive(clap::Args, Debug, Clone)]
pub struct SynthesisArgs {
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

impl SynthesisArgs {
    /// The mask dilation the flags ask for.
    pub fn dilation(&self) -> Dilation {
        let r = self.dilate_radius;
        match self.dilation {
            DilationKind::None => Dilation::None,
            DilationKind::Square => Dilation::Square(r),
            DilationKind::Ellipse => Dilation::Ellipse(r),
            DilationKind::BackgroundSide => Dilation::BackgroundSide(r),
            DilationKind::ForegroundSide => Dilation::ForegroundSide(r),
        }
    }

    /// The inpainter the flags ask for (an ONNX network is opened here,
    /// with `runtime`).
    pub fn inpainter(&self, runtime: &OnnxArgs) -> anyhow::Result<Box<dyn Inpainter>> {
        Ok(match &self.inpaint {
            InpaintKind::Background => Box::new(BackgroundFill::default()),
            InpaintKind::Isotropic => Box::new(IsotropicFill),
            InpaintKind::Onnx(model) => {
                let card = self
                    .inpaint_card
                    .as_deref()
                    .context("--inpaint onnx:MODEL needs --inpaint-card NAME|FILE.json")?;
                let net = OnnxInpainter::open(model, ModelCard::load(card)?, &runtime.options()?)?;
                runtime.report_fallback(&model.display().to_string(), net.device());
                Box::new(net)
            }
        })
    }

    /// The inpainting model file, if any (an input no output may replace).
    pub fn model_file(&self) -> Option<&std::path::Path> {
        match &self.inpaint {
            InpaintKind::Onnx(model) => Some(model),
            _ => None,
        }
    }

    /// The settings as the manifest's provenance records them.
    pub fn provenance(&self) -> serde_json::Value {
        serde_json::json!({
            "dilation": format!("{:?}", self.dilation()),
            "inpaint": match &self.inpaint {
                InpaintKind::Background => "background".to_string(),
                InpaintKind::Isotropic => "isotropic".to_string(),
                InpaintKind::Onnx(model) => format!("onnx:{}", model.display()),
            },
            "inpaint_card": self.inpaint_card,
        })
    }
}
