//! A step split into shares: over this process's devices (a thread per
//! device, each with a copy of both networks), and over processes (the MPI
//! ranks of a run, each holding its share of the batch). Each share's
//! gradient is of its loss weighted by its share of the step's items; the
//! shares' gradients meet through a [`GradientReduction`] and their loss
//! values through the processes' gather ([`super::wire`]), and the one
//! process's (or every rank's) trainer then steps once, identically.

use burn::tensor::Device;

use super::objective::LossValues;
use super::reduce::{GradientReduction, InProcessSum, ShareGradients};
use super::{S3Trainer, StepReport, unshareable};
use crate::data::StepBatch;
use crate::distributed::Collective;
use crate::error::TrainError;
use mbs_nets::{Backbone, NetError};

/// Where the shares of one step run and how they meet.
pub struct Sharing<'a, B: Backbone> {
    /// This process's devices, one share of its items each; the first is
    /// the student's (where the gradients are summed).
    pub devices: &'a [Device],
    /// The items of the whole step, over every process.
    pub items: usize,
    /// How the shares' gradients are summed, and over which processes
    /// (those that exchange their loss values).
    pub reduction: &'a dyn GradientReduction<B>,
}

/// A share's gradients and loss values, its weight (its share of the
/// step's items) and the student copy that computed them.
struct ShareResult<B> {
    gradients: ShareGradients<B>,
    values: LossValues,
    weight: f64,
}

impl<B: Backbone> S3Trainer<B> {
    /// Takes one optimisation step on `batch` split across `devices`, data
    /// parallel: each device gets a share of the items (in order, sizes
    /// differing by at most one), a copy of both networks, and computes the
    /// gradient of its share's loss in a thread of its own. The gradients,
    /// each weighted by its share of the items, are summed on the student's
    /// device, where clipping, the optimiser and the EMA teacher update
    /// once, as in [`Self::step`]; the next step copies the updated weights
    /// out again, so every device starts each step from the same weights.
    /// Each share's loss is normalised over its own items, as in PyTorch's
    /// DistributedDataParallel. With one device this is [`Self::step`].
    pub fn step_parallel(
        &mut self,
        batch: StepBatch,
        devices: &[Device],
    ) -> Result<StepReport, TrainError> {
        if devices.len() <= 1 {
            return self.step(batch);
        }
        let items = batch.reference.dims()[0];
        let sharing = Sharing {
            devices,
            items,
            reduction: &InProcessSum,
        };
        self.step_shared(batch, &sharing)
    }

    /// Takes this process's part of one optimisation step whose items are
    /// shared as `sharing` says: `batch` holds this process's items (rank r
    /// holds share r of the step's, as [`mbs_batch::share`] deals them),
    /// split again over its devices. Every share's gradient is of its loss
    /// weighted by its share of all the step's items; the gradients are
    /// summed by `sharing.reduction`: first on this process (read back
    /// into one buffer when processes sum it), then the processes exchange
    /// their loss values and check that their buffers are as long, then
    /// the buffers are summed over the processes; and
    /// each process clips, steps the optimiser and updates its teacher
    /// identically, so the weights stay the same everywhere (see
    /// [`crate::distributed::check_same_weights`]). The report is the
    /// whole step's, on every process.
    pub fn step_shared(
        &mut self,
        batch: StepBatch,
        sharing: &Sharing<'_, B>,
    ) -> Result<StepReport, TrainError> {
        if let Some(processes) = sharing.reduction.processes()
            && let Some(message) = unshareable(sharing.items, processes.size(), "processes")
        {
            return Err(TrainError::Distributed(message));
        }
        let local = batch.reference.dims()[0];
        if let Some(message) = unshareable(local, sharing.devices.len(), "devices") {
            return Err(TrainError::Config(message));
        }
        let (gradients, values): (Vec<_>, Vec<_>) = self
            .share_gradients(batch, sharing)?
            .into_iter()
            .map(|share| (share.gradients, (share.values, share.weight)))
            .unzip();
        let reduction = sharing.reduction;
        // Flattening may fail (reading back from the device): it comes
        // before the gather, so that no rank waits in it for one that failed.
        let local = reduction.local_sum(&self.student, gradients, &sharing.devices[0])?;
        let values = match reduction.processes() {
            // A process of its own: its shares' values weighted by their
            // share of the step's items (a lone share's weight is 1).
            None => LossValues::weighted_sum(&values),
            Some(processes) => exchange_values(&values, local.length(), processes)?,
        };
        let grads = reduction.sum_over_processes(&self.student, local)?;
        self.apply(grads, values)
    }

    /// Each share's gradients and loss values: on the student itself when
    /// this process has one device, else on a copy per device, each in a
    /// thread of its own.
    fn share_gradients(
        &self,
        batch: StepBatch,
        sharing: &Sharing<'_, B>,
    ) -> Result<Vec<ShareResult<B>>, TrainError> {
        let weight_of = |share: &StepBatch| share.reference.dims()[0] as f64 / sharing.items as f64;
        if let [_] = sharing.devices {
            let weight = weight_of(&batch);
            return Ok(vec![self.own_share(batch, weight)?]);
        }
        let (geometry_weight, scale) = (self.geometry_weight(), self.scale());
        let shares = batch.split(sharing.devices.len());
        let objective = &self.objective;
        std::thread::scope(|scope| {
            let workers: Vec<_> = shares
                .into_iter()
                .zip(sharing.devices)
                .map(|(share, device)| {
                    let weight = weight_of(&share);
                    let replica = self.student.clone().fork(&device.clone().autodiff());
                    let teacher = self.teacher.clone().to_device(device);
                    let share = share.to_device(device);
                    scope.spawn(move || {
                        let (grads, values) = objective.gradients(
                            &teacher,
                            &replica,
                            share,
                            weight * scale,
                            geometry_weight,
                        )?;
                        let gradients = ShareGradients { grads, replica };
                        Ok(ShareResult {
                            gradients,
                            values,
                            weight,
                        })
                    })
                })
                .collect();
            workers
                .into_iter()
                .zip(sharing.devices)
                .map(|(worker, device)| worker.join().unwrap_or_else(|_| Err(panicked(device))))
                .collect()
        })
    }

    /// The gradients and loss values of `batch`, whose loss weighs
    /// `weight`, computed by the student itself.
    fn own_share(&self, batch: StepBatch, weight: f64) -> Result<ShareResult<B>, TrainError> {
        let (grads, values) = self.objective.gradients(
            &self.teacher,
            &self.student,
            batch,
            weight * self.scale(),
            self.geometry_weight(),
        )?;
        let replica = self.student.clone();
        Ok(ShareResult {
            gradients: ShareGradients { grads, replica },
            values,
            weight,
        })
    }
}

/// The whole step's loss values, from every process's shares: each
/// process sends its shares' `values` (combined, with their total weight)
/// and the `length` of its gradient buffer, which must be the same
/// everywhere before the buffers are summed.
fn exchange_values(
    values: &[(LossValues, f64)],
    length: usize,
    processes: &dyn Collective,
) -> Result<LossValues, TrainError> {
    let weight: f64 = values.iter().map(|(_, weight)| weight).sum();
    let mine = match values {
        [(one, _)] => *one,
        _ => LossValues::weighted_sum(&relative_to(values, weight)),
    };
    let all = processes
        .gather(&mine.encode(weight, length))
        .iter()
        .map(|bytes| LossValues::decode(bytes))
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| TrainError::Distributed("a rank sent unreadable loss values".into()))?;
    if let Some(rank) = all.iter().position(|(_, _, len)| *len != length) {
        return Err(TrainError::Distributed(format!(
            "rank {rank} computed {} gradient values where rank {} computed {length}: the \
             processes do not train the same network",
            all[rank].2,
            processes.rank(),
        )));
    }
    let weighted: Vec<_> = all.into_iter().map(|(v, w, _)| (v, w)).collect();
    Ok(LossValues::weighted_sum(&weighted))
}

/// Each share's values with its weight divided by `total`.
fn relative_to(values: &[(LossValues, f64)], total: f64) -> Vec<(LossValues, f64)> {
    values
        .iter()
        .map(|(values, weight)| (*values, weight / total))
        .collect()
}

/// The error of a device whose share's thread panicked.
fn panicked(device: &Device) -> TrainError {
    NetError::Device {
        name: format!("{device:?}"),
        reason: "its share of the step failed (the runtime panicked)".into(),
    }
    .into()
}
