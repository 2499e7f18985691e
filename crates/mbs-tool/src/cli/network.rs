//! The trained-network flags of `predict` and `eval`: a training run's
//! teacher (`--checkpoint`) or a backbone with weights from a file
//! (`--backbone`, `--weights`, `--set network.KEY=VALUE`).

use std::path::PathBuf;

use anyhow::{Context, bail};
use mbs_train::RunConfig;
use mbs_train::inference::NetworkMatcher;

/// Flags choosing a trained network.
#[derive(clap::Args)]
pub struct NetworkArgs {
    /// Predict with the teacher of a training run (or of one of its
    /// checkpoints/step-N folders).
    #[arg(long, value_name = "RUN|CHECKPOINT", conflicts_with = "weights")]
    pub checkpoint: Option<PathBuf>,
    /// Predict with --backbone and these weights: an official checkpoint
    /// (.pth or .safetensors, with or without DataParallel's `module.`
    /// prefix) or an `mbs-tool export`.
    #[arg(long, value_name = "FILE", requires = "backbone")]
    pub weights: Option<PathBuf>,
    /// The network of --weights: compact, raft-stereo or igev.
    #[arg(long, value_name = "NAME", requires = "weights")]
    pub backbone: Option<String>,
    /// A network setting for --weights (repeatable), e.g.
    /// `network.raft_stereo.n_downsample=3` or `network.raft_stereo.test_iters=12`.
    #[arg(long = "set", value_name = "network.KEY=VALUE", requires = "weights")]
    pub set: Vec<String>,
}

impl NetworkArgs {
    /// The chosen network, if any, on `device` (see
    /// [`mbs_train::device::open_device`]).
    pub fn matcher(&self, device: &str) -> anyhow::Result<Option<NetworkMatcher>> {
        if self.checkpoint.is_none() && self.weights.is_none() {
            return Ok(None);
        }
        let device = mbs_train::device::open_device(device)?;
        if let Some(path) = &self.checkpoint {
            return Ok(Some(NetworkMatcher::open(path, device)?));
        }
        let (Some(weights), Some(backbone)) = (&self.weights, &self.backbone) else {
            return Ok(None);
        };
        if let Some(other) = self.set.iter().find(|s| !s.starts_with("network.")) {
            bail!("--set {other}: only network.* settings apply to --weights");
        }
        let mut overrides = vec![format!("network.backbone={backbone}")];
        overrides.extend(self.set.iter().cloned());
        let config = RunConfig::layered(None, &overrides).context("the network settings")?;
        Ok(Some(NetworkMatcher::with_weights(
            &config.network,
            weights,
            device,
        )?))
    }
}
