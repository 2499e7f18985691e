//! Where a run trains: its devices and the processes it is spread over,
//! checked against the run's settings once, before anything is read or
//! written.

use std::rc::Rc;

use burn::tensor::Device;

use crate::config::RunConfig;
use crate::distributed::Collective;
use crate::error::TrainError;
use crate::precision::check_support;

/// The devices a run trains on (the first holds the weights; all share
/// each step's batch) and the processes it is spread over (`None`: this
/// one alone), as [`Placement::check`] accepted them.
pub struct Placement {
    pub(super) devices: Vec<Device>,
    pub(super) processes: Option<Rc<dyn Collective>>,
}

impl Placement {
    /// Accepts `devices` (each with the name errors give it) and
    /// `processes` for a run with `config`: one device per process of
    /// several, no more sharers than batch items, and the run's precision
    /// on every device. Open the run with the same `config`.
    pub fn check(
        config: &RunConfig,
        devices: Vec<(String, Device)>,
        processes: Option<Rc<dyn Collective>>,
    ) -> Result<Self, TrainError> {
        if devices.is_empty() {
            return Err(TrainError::Config("no device to train on".into()));
        }
        if let Some(processes) = processes.as_ref().filter(|_| devices.len() > 1) {
            return Err(TrainError::Distributed(format!(
                "each of the {} processes trains on one device, not {}: give one device per \
                 process",
                processes.size(),
                devices.len()
            )));
        }
        // What shares each batch: the processes, or this one's devices.
        let (sharers, what) = match &processes {
            Some(processes) => (processes.size(), "processes"),
            None => (devices.len(), "devices"),
        };
        if config.data.batch_size < sharers {
            return Err(TrainError::Config(format!(
                "data.batch_size {} is smaller than the {sharers} {what} that share it",
                config.data.batch_size
            )));
        }
        let named = devices.iter().map(|(name, device)| (name.clone(), device));
        check_support(config.trainer.precision, named)?;
        Ok(Self {
            devices: devices.into_iter().map(|(_, device)| device).collect(),
            processes,
        })
    }

    /// One process on the CPU.
    pub fn cpu(config: &RunConfig) -> Result<Self, TrainError> {
        Self::check(config, vec![("cpu".into(), Device::flex())], None)
    }
}
