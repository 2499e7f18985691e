//! Where disparities come from, for `predict`, `eval` and `extrapolate`:
//! one set of flags, turned into one [`StereoMatcher`] here. The sources
//! are the built-in semi-global matcher (the default, with the command's
//! own preset), an ONNX stereo network with its card (`--model`,
//! `--card`), a training run's teacher (`--checkpoint`), or an official or
//! exported network (`--backbone`, `--weights`); networks and ONNX models
//! run on `--device`.

use std::error::Error;
use std::path::PathBuf;

use anyhow::Context;
use clap::ValueEnum;
use mbs_core::formats::rgb::read_rgb;
use mbs_core::inputs::InputFiles;
use mbs_core::{FloatImage, RgbImage};
use mbs_dataset::StereoPair;
use mbs_eval::Predictor;
use mbs_infer::onnx::{ModelCard, OnnxStereo};
use mbs_infer::{Disparity, InferError, Sgm, SgmConfig, SgmPaths, StereoMatcher};
use mbs_nets::checkpoint::TrainedNetworks;
use mbs_nets::device::DeviceName;
use mbs_nets::{BackboneKind, NetworkConfig, NetworkMatcher};

use crate::cli::onnx::OnnxArgs;

/// Flags choosing the disparity source.
#[derive(clap::Args)]
pub struct StereoSourceArgs {
    /// An ONNX stereo network instead of the built-in matcher.
    #[arg(long, value_name = "FILE.onnx", requires = "card", conflicts_with_all = ["checkpoint", "weights"], help_heading = "Disparity source")]
    pub model: Option<PathBuf>,
    /// How to feed --model: a built-in card name (crestereo, hitnet,
    /// raft-stereo, igev) or a card FILE.json.
    #[arg(
        long,
        value_name = "NAME|FILE.json",
        requires = "model",
        help_heading = "Disparity source"
    )]
    pub card: Option<String>,
    /// The teacher of a training run (or of one of its checkpoints/step-N
    /// folders) instead of the built-in matcher.
    #[arg(
        long,
        value_name = "RUN|CHECKPOINT",
        conflicts_with = "weights",
        help_heading = "Disparity source"
    )]
    pub checkpoint: Option<PathBuf>,
    /// --backbone with these weights instead of the built-in matcher: an
    /// official checkpoint (.pth or .safetensors, with or without
    /// DataParallel's `module.` prefix) or an `mbs-tool export`.
    #[arg(
        long,
        value_name = "FILE",
        requires = "backbone",
        help_heading = "Disparity source"
    )]
    pub weights: Option<PathBuf>,
    /// The network of --weights: compact, raft-stereo or igev.
    #[arg(long, value_name = "NAME", requires = "weights", value_parser = crate::cli::values::backbone, help_heading = "Disparity source")]
    pub backbone: Option<BackboneKind>,
    /// A network setting for --weights (repeatable), e.g.
    /// `network.raft_stereo.n_downsample=3` or `network.raft_stereo.test_iters=12`.
    #[arg(
        long = "set",
        value_name = "network.KEY=VALUE",
        requires = "weights",
        help_heading = "Disparity source"
    )]
    pub set: Vec<String>,
    /// Number of disparities the built-in matcher searches, up to 4096 (0 =
    /// estimate per pair, at most 256) [default: a Middlebury or ETH3D
    /// scene's calib.txt ndisp, else the command's]; with a network, the
    /// top of --color's scale (0 = each map's maximum).
    #[arg(long, value_name = "N", value_parser = crate::cli::values::sgm_disparities, help_heading = "Disparity source")]
    pub max_disparity: Option<u32>,
    /// Aggregation paths of the built-in matcher [default: the command's].
    #[arg(long, value_enum, help_heading = "Disparity source")]
    pub paths: Option<Paths>,
    /// Leave pixels the built-in matcher could not match invalid instead
    /// of filling them from the background side.
    #[arg(long, help_heading = "Disparity source")]
    pub no_fill: bool,
    /// Where networks run, and the ONNX Runtime library.
    #[command(flatten)]
    pub runtime: OnnxArgs,
}

/// Aggregation paths (see `mbs_infer::SgmPaths`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Paths {
    /// Horizontal and top-down paths: one pass, fastest.
    #[value(name = "5")]
    Five,
    /// All eight directions: more accurate, about 1.6x the time.
    #[value(name = "8")]
    Eight,
}

/// The disparity source the flags chose.
pub enum StereoSource {
    /// The built-in matcher with the command's preset and the flags' settings.
    BuiltIn(SgmConfig),
    /// A network: ONNX, a run's teacher, or official or exported weights.
    Network(Box<dyn StereoMatcher>),
}

impl StereoSourceArgs {
    /// Opens the chosen source; `preset` is the command's built-in matcher,
    /// which the flags adjust.
    pub fn open(&self, preset: SgmConfig) -> anyhow::Result<StereoSource> {
        if self.no_fill && self.uses_network() {
            // It would only rename the maps (Middlebury's sparse `_s` name).
            anyhow::bail!("--no-fill is for the built-in matcher: networks predict every pixel");
        }
        if let (Some(model), Some(card)) = (&self.model, &self.card) {
            let stereo = OnnxStereo::open(model, ModelCard::load(card)?, &self.runtime.options()?)?;
            self.runtime
                .report_fallback(&model.display().to_string(), stereo.device());
            return Ok(StereoSource::Network(Box::new(stereo)));
        }
        if let Some(path) = &self.checkpoint {
            let device = self.runtime.device.open()?;
            return Ok(StereoSource::Network(Box::new(NetworkMatcher::open(
                path, device,
            )?)));
        }
        if let (Some(weights), Some(backbone)) = (&self.weights, self.backbone) {
            let config = NetworkConfig::with_overrides(backbone, &self.set)
                .context("the network settings (--set)")?;
            let device = self.runtime.device.open()?;
            return Ok(StereoSource::Network(Box::new(
                NetworkMatcher::with_weights(&config, weights, device)?,
            )));
        }
        Ok(StereoSource::BuiltIn(SgmConfig {
            max_disparity: self.max_disparity.unwrap_or(preset.max_disparity),
            paths: match self.paths {
                Some(Paths::Five) => SgmPaths::Five,
                Some(Paths::Eight) => SgmPaths::Eight,
                None => preset.paths,
            },
            fill: preset.fill && !self.no_fill,
            ..preset
        }))
    }

    /// Refuses a `--device` that nothing would use: the built-in matcher
    /// runs on the CPU. For commands whose `--device` serves only the
    /// disparity source (`extrapolate`'s also serves an ONNX inpainter).
    pub fn refuse_unused_device(&self) -> anyhow::Result<()> {
        if !self.uses_network() && self.runtime.device != DeviceName::Cpu {
            anyhow::bail!(
                "--device {}: the built-in matcher runs on the CPU; --device is for networks \
                 (--model, --checkpoint, --weights)",
                self.runtime.device
            );
        }
        Ok(())
    }

    /// Adds the files the source reads to `inputs`, so that no output
    /// replaces one: the model, the card file, the weights file, and the
    /// files of the run's or checkpoint's newest checkpoint.
    pub fn add_files_to(&self, inputs: &mut InputFiles) {
        inputs.extend(self.files_read());
    }

    /// The files the source reads: the model, the card file (a built-in
    /// card's name is none), the weights file, and the files of the run's
    /// or checkpoint's newest checkpoint.
    fn files_read(&self) -> Vec<PathBuf> {
        let card = self
            .card
            .as_ref()
            .map(PathBuf::from)
            .filter(|p| p.is_file());
        let mut files: Vec<PathBuf> = [&self.model, &card, &self.weights]
            .into_iter()
            .flatten()
            .cloned()
            .collect();
        if let Some(checkpoint) = &self.checkpoint {
            files.extend(TrainedNetworks::files_read_from(checkpoint));
        }
        files
    }

    /// The source as a rerun into the same output folder must repeat it
    /// (`mbs_core::batch_settings`): each file it reads, by name and
    /// sha256 (so a run's newer teacher is another source), and its other
    /// flags.
    pub fn settings(&self) -> anyhow::Result<serde_json::Value> {
        let files = self
            .files_read()
            .iter()
            .map(|file| {
                let name = file.file_name().map(|n| n.to_string_lossy().into_owned());
                let sha256 = mbs_dataset::checksum::sha256_file(file)
                    .with_context(|| format!("{}: cannot read it", file.display()))?;
                Ok(serde_json::json!({ "file": name, "sha256": sha256 }))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        Ok(serde_json::json!({
            "files": files,
            "card": self.card,
            "backbone": self.backbone.map(|b| format!("{b:?}")),
            "set": self.set,
            "max_disparity": self.max_disparity,
            "paths": self.paths.map(|p| format!("{p:?}")),
            "no_fill": self.no_fill,
        }))
    }

    /// Whether a network (ONNX, a run, weights) predicts, not the built-in
    /// matcher.
    fn uses_network(&self) -> bool {
        self.model.is_some() || self.checkpoint.is_some() || self.weights.is_some()
    }

    /// The chosen source as a matcher of listed pairs (see
    /// [`StereoSourceArgs::open`]).
    pub fn matcher(&self, preset: SgmConfig) -> anyhow::Result<PairMatcher> {
        let matcher: Box<dyn StereoMatcher> = match self.open(preset)? {
            StereoSource::BuiltIn(config) => Box::new(Sgm::new(config)),
            StereoSource::Network(network) => network,
        };
        Ok(PairMatcher {
            matcher,
            pair_bounds: self.max_disparity.is_none(),
        })
    }
}

/// The chosen disparity source for listed pairs: a pair whose dataset
/// bounds its disparities (Middlebury's and ETH3D's `calib.txt` `ndisp`)
/// is searched within that bound unless `--max-disparity` fixed the range.
pub struct PairMatcher {
    matcher: Box<dyn StereoMatcher>,
    /// Whether the pairs' own bounds apply (no `--max-disparity`).
    pair_bounds: bool,
}

impl PairMatcher {
    /// The source's name, for logs and tables.
    pub fn name(&self) -> &str {
        self.matcher.name()
    }

    /// The disparity of `pair` from its views `reference` and `target`.
    pub fn predict(
        &self,
        pair: &StereoPair,
        reference: &RgbImage,
        target: &RgbImage,
    ) -> Result<Disparity, InferError> {
        match pair.disparity_bound.filter(|_| self.pair_bounds) {
            Some(bound) => self
                .matcher
                .predict_toward_within(reference, target, pair.side, bound),
            None => self.matcher.predict_toward(reference, target, pair.side),
        }
    }
}

/// `eval` and `benchmark` score the pairs the source predicts from their
/// views.
impl Predictor for PairMatcher {
    fn predict(&self, pair: &StereoPair) -> Result<FloatImage, Box<dyn Error + Send + Sync>> {
        let reference = read_rgb(&pair.reference)?;
        let target = read_rgb(&pair.target)?;
        Ok(PairMatcher::predict(self, pair, &reference, &target)?.disparity)
    }
}
