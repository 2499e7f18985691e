//! Where a run trains, as a strategy: the devices of this process, one or
//! several ([`Devices`]), or the ranks of an MPI job, each
//! on one device or several ([`Ranks`]). A strategy answers what differs
//! between them: which items of each batch this process loads, whether it
//! writes the run's files, how a stop is voted, how the weights are checked
//! equal, and how one step runs (and so how its gradients are summed, see
//! [`GradientReduction`](crate::step::GradientReduction)). [`place`]
//! checks the devices and processes against the run's settings once,
//! before anything is read or written, and picks the strategy.

use std::ops::Range;
use std::rc::Rc;

use burn::tensor::Device;
use mbs_batch::share;

use crate::config::RunConfig;
use crate::data::StepBatch;
use crate::distributed::{Collective, check_same_weights};
use crate::error::TrainError;
use crate::precision::check_support;
use crate::step::{GradientReduction, HostAllReduce, S3Trainer, Sharing, StepReport};
use mbs_nets::Backbone;

/// How a run trains on its placement; see the module's documentation.
pub trait Strategy<B: Backbone> {
    /// This process's devices: the first holds the weights and validates.
    fn devices(&self) -> &[Device];
    /// The items of each batch of `batch_size` that this process loads.
    fn items_loaded(&self, batch_size: usize) -> Range<usize>;
    /// Whether this process writes the run's files and validates.
    fn writes(&self) -> bool;
    /// Whether the run stops after this step, when this process was
    /// `asked` to (all processes of a run stop at the same step).
    fn stop_voted(&self, asked: bool) -> bool;
    /// Checks that every process holds the same `networks` after `steps`
    /// steps (nothing to check in a process of its own).
    fn check_same_weights(&self, networks: [&B; 2], steps: usize) -> Result<(), TrainError>;
    /// Where this process's batches are built from the loaded images: on
    /// its one device, or on the host when several share them (the
    /// shares then go to their devices from there, not through the first).
    fn batch_device(&self) -> Device {
        match self.devices() {
            [one] => one.clone(),
            _ => Device::flex(),
        }
    }
    /// One optimisation step of `trainer` on this process's items of a
    /// batch of `batch_size`.
    fn step(
        &self,
        trainer: &mut S3Trainer<B>,
        batch: StepBatch,
        batch_size: usize,
    ) -> Result<StepReport, TrainError>;
}

/// One process on one device or several: each takes a share of every
/// batch and the gradients are summed on the first
/// ([`InProcessSum`](crate::step::InProcessSum)); on one device, the step
/// is [`S3Trainer::step`] ([`S3Trainer::step_parallel`] falls back to it).
pub struct Devices {
    devices: Vec<Device>,
}

impl<B: Backbone> Strategy<B> for Devices {
    fn devices(&self) -> &[Device] {
        &self.devices
    }
    fn items_loaded(&self, batch_size: usize) -> Range<usize> {
        0..batch_size
    }
    fn writes(&self) -> bool {
        true
    }
    fn stop_voted(&self, asked: bool) -> bool {
        asked
    }
    fn check_same_weights(&self, _: [&B; 2], _: usize) -> Result<(), TrainError> {
        Ok(())
    }
    fn step(
        &self,
        trainer: &mut S3Trainer<B>,
        batch: StepBatch,
        _: usize,
    ) -> Result<StepReport, TrainError> {
        trainer.step_parallel(batch, &self.devices)
    }
}

/// One rank of an MPI job on one device or several: it loads its share of
/// every batch (split again over its devices), the ranks sum their
/// gradients through their reduction ([`HostAllReduce`] unless the run is
/// given another, [`Ranks::new`]) and vote on stopping, and rank 0 alone
/// writes.
pub struct Ranks<B: Backbone> {
    devices: Vec<Device>,
    reduction: Rc<dyn GradientReduction<B>>,
}

impl<B: Backbone> Ranks<B> {
    /// The rank of this process on `devices` whose gradients `reduction`
    /// sums over its processes (those of the run). A reduction over no
    /// processes is refused.
    pub fn new(
        devices: Vec<Device>,
        reduction: Rc<dyn GradientReduction<B>>,
    ) -> Result<Self, TrainError> {
        if reduction.processes().is_none() {
            return Err(TrainError::Config(
                "the gradient reduction of a run over processes sums over none".into(),
            ));
        }
        Ok(Self { devices, reduction })
    }

    /// The processes of the run (those the reduction sums over).
    fn processes(&self) -> &dyn Collective {
        self.reduction
            .processes()
            .expect("a reduction over processes, checked in Ranks::new")
    }
}

impl<B: Backbone> Strategy<B> for Ranks<B> {
    fn devices(&self) -> &[Device] {
        &self.devices
    }
    fn items_loaded(&self, batch_size: usize) -> Range<usize> {
        share(batch_size, self.processes().size(), self.processes().rank())
    }
    fn writes(&self) -> bool {
        self.processes().rank() == 0
    }
    fn stop_voted(&self, asked: bool) -> bool {
        let votes = self.processes().gather(&[u8::from(asked)]);
        votes.iter().any(|vote| vote[0] == 1)
    }
    fn check_same_weights(&self, networks: [&B; 2], steps: usize) -> Result<(), TrainError> {
        check_same_weights(self.processes(), &networks, steps)
    }
    fn step(
        &self,
        trainer: &mut S3Trainer<B>,
        batch: StepBatch,
        batch_size: usize,
    ) -> Result<StepReport, TrainError> {
        let sharing = Sharing {
            devices: &self.devices,
            items: batch_size,
            reduction: self.reduction.as_ref(),
        };
        trainer.step_shared(batch, &sharing)
    }
}

/// The strategy of a run with `config` on `devices` (each with the name
/// errors give it) and `processes` (`None`: this one alone), once they
/// can run it: at least one device, no more sharers than batch items (each
/// device of each process needs one), and the run's precision on every
/// device. The processes sum their gradients through `reduction` when
/// given (it must sum over `processes`), else through [`HostAllReduce`].
pub fn place<B: Backbone + 'static>(
    config: &RunConfig,
    devices: Vec<(String, Device)>,
    processes: Option<Rc<dyn Collective>>,
    reduction: Option<Rc<dyn GradientReduction<B>>>,
) -> Result<Box<dyn Strategy<B>>, TrainError> {
    if devices.is_empty() {
        return Err(TrainError::Config("no device to train on".into()));
    }
    let (sharers, what) = match (&processes, devices.len()) {
        (Some(processes), 1) => (processes.size(), "processes".to_string()),
        (Some(processes), each) => (
            processes.size() * each,
            format!("devices ({} processes of {each})", processes.size()),
        ),
        (None, count) => (count, "devices".to_string()),
    };
    if config.data.batch_size < sharers {
        return Err(TrainError::Config(format!(
            "data.batch_size {} is smaller than the {sharers} {what} that share it",
            config.data.batch_size
        )));
    }
    let named = devices.iter().map(|(name, device)| (name.clone(), device));
    check_support(config.trainer.precision, named)?;
    let devices: Vec<Device> = devices.into_iter().map(|(_, device)| device).collect();
    let Some(processes) = processes else {
        if reduction.is_some() {
            return Err(TrainError::Config(
                "a gradient reduction is given for a run of one process".into(),
            ));
        }
        return Ok(Box::new(Devices { devices }));
    };
    let reduction = reduction.unwrap_or_else(|| Rc::new(HostAllReduce::new(Rc::clone(&processes))));
    let sums_over = reduction.processes().map(|p| (p.rank(), p.size()));
    if sums_over != Some((processes.rank(), processes.size())) {
        return Err(TrainError::Config(format!(
            "the gradient reduction sums over {} but the run is rank {} of {} processes",
            sums_over.map_or("no processes".into(), |(rank, size)| format!(
                "rank {rank} of {size} processes"
            )),
            processes.rank(),
            processes.size()
        )));
    }
    Ok(Box::new(Ranks::new(devices, reduction)?))
}
