//! The backbone a run trains, chosen by `network.backbone`: the compact
//! cost-volume network, RAFT-Stereo or IGEV-Stereo, behind one module type
//! so that runs, checkpoints and inference handle any of them.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use burn::config::Config;
use burn::module::Module;
use burn::tensor::{Device, Tensor};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::igev_stereo::{IgevStereo, IgevStereoConfig};
use super::official::{OfficialLayout, StateDict, export_state_dict, load_state_dict};
use super::{Backbone, CostVolumeNet, CostVolumeNetConfig, RaftStereo, RaftStereoConfig};
use crate::error::NetError;
use crate::ranges;

/// Which network a run trains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BackboneKind {
    /// [`CostVolumeNet`]: 45k parameters, learns on the CPU in minutes.
    Compact,
    /// [`RaftStereo`], the official architecture.
    RaftStereo,
    /// [`IgevStereo`], the official architecture (the paper's main backbone).
    Igev,
}

impl BackboneKind {
    /// Every kind, as `--backbone` spells it.
    pub const NAMES: [&str; 3] = ["compact", "raft-stereo", "igev"];
}

impl fmt::Display for BackboneKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            BackboneKind::Compact => "compact",
            BackboneKind::RaftStereo => "raft-stereo",
            BackboneKind::Igev => "igev",
        })
    }
}

impl FromStr for BackboneKind {
    type Err = NetError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text {
            "compact" => Ok(BackboneKind::Compact),
            "raft-stereo" | "raft_stereo" | "raftstereo" => Ok(BackboneKind::RaftStereo),
            "igev" | "igev-stereo" | "igev_stereo" => Ok(BackboneKind::Igev),
            other => Err(NetError::Config(format!(
                "unknown backbone `{other}`; expected one of {}",
                BackboneKind::NAMES.join(", ")
            ))),
        }
    }
}

/// The `network` part of a run's configuration.
#[derive(Config, Debug)]
pub struct NetworkConfig {
    /// The network trained.
    #[config(default = "BackboneKind::Compact")]
    pub backbone: BackboneKind,
    /// Largest disparity (full-resolution pixels) of the data: the compact
    /// network's candidate range (a multiple of 4) and the colour scale of
    /// the run's pictures for every backbone.
    #[config(default = 192)]
    pub max_disparity: usize,
    /// Settings of the compact network.
    #[config(default = "CostVolumeNetConfig::new()")]
    pub compact: CostVolumeNetConfig,
    /// Settings of RAFT-Stereo (the official options and defaults).
    #[config(default = "RaftStereoConfig::new()")]
    pub raft_stereo: RaftStereoConfig,
    /// Settings of IGEV-Stereo (the official options and defaults).
    #[config(default = "IgevStereoConfig::new()")]
    pub igev: IgevStereoConfig,
}

impl NetworkConfig {
    /// The defaults of `backbone` overlaid with `network.KEY=VALUE`
    /// overrides (the keys of a run's `network` section, e.g.
    /// `network.raft_stereo.n_downsample=3`), checked: the configuration of
    /// a network loaded for inference, with no training settings.
    pub fn with_overrides(backbone: BackboneKind, overrides: &[String]) -> Result<Self, NetError> {
        let mut section = NetworkConfig::new().with_backbone(backbone).to_json()?;
        let relative: Vec<String> = overrides
            .iter()
            .map(|assignment| {
                assignment
                    .strip_prefix("network.")
                    .map(str::to_owned)
                    .ok_or_else(|| {
                        NetError::Config(format!(
                            "`{assignment}`: only network.KEY=VALUE settings apply to a network"
                        ))
                    })
            })
            .collect::<Result<_, _>>()?;
        mbs_core::layered::apply_overrides(&mut section, &relative)
            .map_err(|e| NetError::Config(format!("network.{e}")))?;
        Self::from_json(&section)
    }

    /// A `network` section as a run's configuration saves it, checked; keys
    /// missing from it (added since it was written) take their defaults.
    pub fn from_json(section: &Value) -> Result<Self, NetError> {
        let mut document = NetworkConfig::new().to_json()?;
        mbs_core::layered::merge(&mut document, section);
        let config: NetworkConfig = serde_json::from_value(document)
            .map_err(|e| NetError::Config(format!("network: {e}")))?;
        config.validate()?;
        Ok(config)
    }

    /// The configuration as a JSON value.
    pub fn to_json(&self) -> Result<Value, NetError> {
        serde_json::to_value(self).map_err(|e| NetError::Config(e.to_string()))
    }

    /// Checks the chosen backbone's settings.
    pub fn validate(&self) -> Result<(), NetError> {
        ranges::integer_in(
            "max_disparity",
            self.max_disparity,
            (1, ranges::MAX_DISPARITY),
        )?;
        match self.backbone {
            BackboneKind::Compact => self.compact.validate(self.max_disparity),
            BackboneKind::RaftStereo => self.raft_stereo.validate(),
            BackboneKind::Igev => self.igev.validate(),
        }
    }

    /// The configuration predicting with `iters` iterations; refused for
    /// the compact network and for 0.
    pub fn with_test_iters(mut self, iters: usize) -> Result<Self, NetError> {
        let slot = match self.backbone {
            BackboneKind::Compact => {
                return Err(NetError::Config(
                    "the compact network has no iterations to set".into(),
                ));
            }
            BackboneKind::RaftStereo => &mut self.raft_stereo.test_iters,
            BackboneKind::Igev => &mut self.igev.test_iters,
        };
        *slot = iters;
        self.validate()?;
        Ok(self)
    }

    /// Builds the chosen network with fresh weights on `device`.
    pub fn init(&self, device: &Device) -> Result<StereoNetwork, NetError> {
        Ok(match self.backbone {
            BackboneKind::Compact => {
                StereoNetwork::Compact(self.compact.init(self.max_disparity, device)?)
            }
            BackboneKind::RaftStereo => StereoNetwork::RaftStereo(self.raft_stereo.init(device)?),
            BackboneKind::Igev => StereoNetwork::Igev(self.igev.init(device)?),
        })
    }
}

/// The network of a run (see the module documentation).
// burn's `Module` derive has no `Box` field support; the network is moved
// once per step, which its size does not make noticeable.
#[allow(clippy::large_enum_variant)]
#[derive(Module, Debug)]
pub enum StereoNetwork {
    /// The compact cost-volume network.
    Compact(CostVolumeNet),
    /// RAFT-Stereo.
    RaftStereo(RaftStereo),
    /// IGEV-Stereo.
    Igev(IgevStereo),
}

impl StereoNetwork {
    /// The network with the weights of `path`: an official state dict
    /// (`.pth` or `.safetensors`, official keys) or an export of mbs
    /// ([`StereoNetwork::export`]). The file must match the network's
    /// structure exactly; the error lists what does not.
    pub fn with_weights(self, path: &Path) -> Result<Self, NetError> {
        self.with_state_dict(&StateDict::read(path)?, path)
    }

    /// The network with the weights of `dict` (read from `source`, which
    /// errors name).
    pub fn with_state_dict(self, dict: &StateDict, source: &Path) -> Result<Self, NetError> {
        Ok(match self {
            StereoNetwork::Compact(net) => {
                StereoNetwork::Compact(load_state_dict(net, dict, source)?)
            }
            StereoNetwork::RaftStereo(net) => {
                StereoNetwork::RaftStereo(load_state_dict(net, dict, source)?)
            }
            StereoNetwork::Igev(net) => StereoNetwork::Igev(load_state_dict(net, dict, source)?),
        })
    }

    /// The weights under the official keys (the compact network, which has
    /// no official implementation, under its own parameter paths), and the
    /// batch-norm counter keys an export adds.
    pub fn state_dict(&self) -> (StateDict, Vec<String>) {
        match self {
            StereoNetwork::Compact(net) => export_state_dict(net),
            StereoNetwork::RaftStereo(net) => export_state_dict(net),
            StereoNetwork::Igev(net) => export_state_dict(net),
        }
    }

    /// Writes [`StereoNetwork::state_dict`] to `path` as safetensors, which
    /// the official PyTorch module loads with `load_state_dict`.
    pub fn export(&self, path: &Path) -> Result<(), NetError> {
        let (dict, counters) = self.state_dict();
        dict.write_safetensors(path, &counters)
    }
}

impl OfficialLayout for CostVolumeNet {
    /// No official implementation: the burn paths are the keys.
    fn official_key(path: &str) -> String {
        path.to_string()
    }
}

impl Backbone for StereoNetwork {
    fn disparity(&self, reference: Tensor<4>, target: Tensor<4>) -> Tensor<4> {
        match self {
            StereoNetwork::Compact(net) => net.disparity(reference, target),
            StereoNetwork::RaftStereo(net) => net.disparity(reference, target),
            StereoNetwork::Igev(net) => net.disparity(reference, target),
        }
    }

    fn disparities(&self, reference: Tensor<4>, target: Tensor<4>) -> Vec<Tensor<4>> {
        match self {
            StereoNetwork::Compact(net) => net.disparities(reference, target),
            StereoNetwork::RaftStereo(net) => net.disparities(reference, target),
            StereoNetwork::Igev(net) => net.disparities(reference, target),
        }
    }

    fn initial_estimates(&self) -> usize {
        match self {
            StereoNetwork::Compact(net) => net.initial_estimates(),
            StereoNetwork::RaftStereo(net) => net.initial_estimates(),
            StereoNetwork::Igev(net) => net.initial_estimates(),
        }
    }
}
