//! Gradient reduction, the seam where the shares of a step meet: each
//! share's gradients stay on the device that computed them, and a
//! [`GradientReduction`] turns them into the one sum the optimiser steps
//! with. Two today: [`InProcessSum`] (this process's devices, summed on
//! the first) and [`HostAllReduce`] (that sum, then summed over the ranks
//! of an MPI job through one host buffer). A device-side collective
//! (NCCL, burn's collective) is one more implementation, written anywhere:
//! its local sum stays on the device ([`LocalGradients::on_device`] counts
//! its length for the processes' check), and a run takes it through
//! [`crate::launch::Launch::reduction`].

use std::rc::Rc;

use burn::module::Module;
use burn::optim::{GradientsAccumulator, GradientsParams};
use burn::tensor::Device;

use crate::distributed::{Collective, FlatGradients, gradient_length};
use crate::error::TrainError;
use mbs_nets::Backbone;

/// The gradients of one share of a step, on the device that computed them.
pub struct ShareGradients<B> {
    /// The gradients of the share's (weighted) loss.
    pub grads: GradientsParams,
    /// The copy of the student that computed them (its parameters say
    /// where each gradient lives).
    pub replica: B,
}

/// How the gradients of a step's shares become their sum, in two steps
/// so that the processes can check, between them, that they are about to
/// sum buffers of the same length: this process's sum
/// ([`Self::local_sum`]), then the sum over the processes
/// ([`Self::sum_over_processes`]). The reduction owns the processes it
/// sums over, so that the processes that exchange loss values are always
/// those whose gradients are summed.
pub trait GradientReduction<B: Backbone> {
    /// The processes whose gradients this sums and that exchange their
    /// loss values (`None`: this process alone).
    fn processes(&self) -> Option<&dyn Collective>;
    /// The sum of `shares` (this process's, at least one) on `home` (the
    /// device of `student`, the network the optimiser steps), in the form
    /// [`Self::sum_over_processes`] takes.
    fn local_sum(
        &self,
        student: &B,
        shares: Vec<ShareGradients<B>>,
        home: &Device,
    ) -> Result<LocalGradients, TrainError>;
    /// The sum over every process of each one's `local` sum, as the
    /// optimiser takes it.
    fn sum_over_processes(
        &self,
        student: &B,
        local: LocalGradients,
    ) -> Result<GradientsParams, TrainError>;
}

/// One process's sum of its shares' gradients, with the number of values
/// the processes are about to sum (every process must have as many).
pub enum LocalGradients {
    /// On the student's device: the sum of a process that trains alone,
    /// or one that a device-side collective sums over the processes.
    OnDevice {
        /// The gradients.
        grads: GradientsParams,
        /// The number of values they hold ([`gradient_length`]).
        length: usize,
    },
    /// Read back into one host buffer, ready for the processes' sum.
    OnHost(FlatGradients),
}

impl LocalGradients {
    /// `grads` of `student`'s parameters, on their device.
    pub fn on_device<M: Module>(student: &M, grads: GradientsParams) -> Self {
        let length = gradient_length(student, &grads);
        Self::OnDevice { grads, length }
    }

    /// The number of gradient values the processes are about to sum.
    pub fn length(&self) -> usize {
        match self {
            Self::OnDevice { length, .. } => *length,
            Self::OnHost(flat) => flat.values.len(),
        }
    }

    /// The gradients as they are, on the device.
    pub fn into_device(self) -> GradientsParams {
        match self {
            Self::OnDevice { grads, .. } => grads,
            Self::OnHost(flat) => flat.into_grads(),
        }
    }
}

/// The shares of one process, summed on its first device: a lone share's
/// gradients are used as they are.
#[derive(Debug, Clone, Copy, Default)]
pub struct InProcessSum;

impl<B: Backbone> GradientReduction<B> for InProcessSum {
    fn processes(&self) -> Option<&dyn Collective> {
        None
    }

    fn local_sum(
        &self,
        student: &B,
        mut shares: Vec<ShareGradients<B>>,
        home: &Device,
    ) -> Result<LocalGradients, TrainError> {
        if shares.len() == 1 {
            return Ok(LocalGradients::on_device(student, shares.remove(0).grads));
        }
        let mut sum = GradientsAccumulator::<B>::new();
        for share in shares {
            sum.accumulate(student, share.grads.to_device(home, &share.replica));
        }
        Ok(LocalGradients::on_device(student, sum.grads()))
    }

    fn sum_over_processes(
        &self,
        _: &B,
        local: LocalGradients,
    ) -> Result<GradientsParams, TrainError> {
        Ok(local.into_device())
    }
}

/// The process's sum ([`InProcessSum`]), then summed over the processes
/// of an MPI job: read back into one host buffer ([`FlatGradients`]),
/// all-reduced in one call and put back on the device.
#[derive(Clone)]
pub struct HostAllReduce {
    processes: Rc<dyn Collective>,
}

impl HostAllReduce {
    /// Sums over `processes`.
    pub fn new(processes: Rc<dyn Collective>) -> Self {
        Self { processes }
    }
}

impl<B: Backbone> GradientReduction<B> for HostAllReduce {
    fn processes(&self) -> Option<&dyn Collective> {
        Some(self.processes.as_ref())
    }

    fn local_sum(
        &self,
        student: &B,
        shares: Vec<ShareGradients<B>>,
        home: &Device,
    ) -> Result<LocalGradients, TrainError> {
        let local = InProcessSum.local_sum(student, shares, home)?.into_device();
        Ok(LocalGradients::OnHost(FlatGradients::gather(
            student, &local,
        )?))
    }

    fn sum_over_processes(
        &self,
        student: &B,
        local: LocalGradients,
    ) -> Result<GradientsParams, TrainError> {
        // This reduction's `local_sum` is always on the host; a sum handed
        // over on the device is read back first, so that it is still summed.
        let mut flat = match local {
            LocalGradients::OnHost(flat) => flat,
            LocalGradients::OnDevice { grads, .. } => FlatGradients::gather(student, &grads)?,
        };
        flat.sum_over(self.processes.as_ref());
        Ok(flat.into_grads())
    }
}
