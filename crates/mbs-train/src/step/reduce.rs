//! Gradient reduction, the seam where the shares of a step meet: each
//! share's gradients stay on the device that computed them, and a
//! [`GradientReduction`] turns them into the one sum the optimiser steps
//! with. Two today: [`InProcessSum`] (this process's devices, summed on
//! the first) and [`HostAllReduce`] (that sum, then summed over the ranks
//! of an MPI job through one host buffer). A device-side collective
//! (NCCL, burn's collective) would be one more implementation.

use std::rc::Rc;

use burn::optim::{GradientsAccumulator, GradientsParams};
use burn::tensor::Device;

use crate::distributed::{Collective, FlatGradients};
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

/// How the gradients of a step's shares become their sum.
pub trait GradientReduction<B: Backbone> {
    /// The sum, over every participant of the step, of the gradients of
    /// `shares` (this process's, at least one), on `home` (the device of
    /// `student`, the network the optimiser steps).
    fn reduce(
        &self,
        student: &B,
        shares: Vec<ShareGradients<B>>,
        home: &Device,
    ) -> Result<GradientsParams, TrainError>;
}

/// The shares of one process, summed on its first device: a lone share's
/// gradients are used as they are.
#[derive(Debug, Clone, Copy, Default)]
pub struct InProcessSum;

impl<B: Backbone> GradientReduction<B> for InProcessSum {
    fn reduce(
        &self,
        student: &B,
        mut shares: Vec<ShareGradients<B>>,
        home: &Device,
    ) -> Result<GradientsParams, TrainError> {
        if shares.len() == 1 {
            return Ok(shares.remove(0).grads);
        }
        let mut sum = GradientsAccumulator::<B>::new();
        for share in shares {
            sum.accumulate(student, share.grads.to_device(home, &share.replica));
        }
        Ok(sum.grads())
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
    fn reduce(
        &self,
        student: &B,
        shares: Vec<ShareGradients<B>>,
        home: &Device,
    ) -> Result<GradientsParams, TrainError> {
        let local = InProcessSum.reduce(student, shares, home)?;
        let mut flat = FlatGradients::gather(student, &local)?;
        flat.sum_over(self.processes.as_ref());
        Ok(flat.into_grads())
    }
}

/// The number of gradient values `grads` holds for `student`'s float
/// parameters: what every process of a step must agree on before their
/// gradients are summed.
pub(super) fn gradient_length<B: Backbone>(student: &B, grads: &GradientsParams) -> usize {
    let mut count = CountGradients { grads, length: 0 };
    student.visit(&mut count);
    count.length
}

/// Counts the gradient values of the parameters it visits.
struct CountGradients<'a> {
    grads: &'a GradientsParams,
    length: usize,
}

impl burn::module::ModuleVisitor for CountGradients<'_> {
    fn visit_float<const D: usize>(
        &mut self,
        param: &burn::module::Param<burn::tensor::Tensor<D>>,
    ) {
        if let Some(grad) = self.grads.get::<D>(param.id) {
            self.length += grad.dims().iter().product::<usize>();
        }
    }
}
