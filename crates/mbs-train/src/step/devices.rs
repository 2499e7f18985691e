//! Data parallel on several devices of one process: a thread per device
//! computes its share's gradients; they are summed on the first device,
//! which steps once.

use burn::optim::GradientsAccumulator;
use burn::tensor::Device;

use super::objective::LossValues;
use super::{S3Trainer, StepReport, unshareable};
use crate::data::StepBatch;
use crate::error::TrainError;
use mbs_nets::{Backbone, NetError};

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
        if let Some(message) = unshareable(items, devices.len(), "devices") {
            return Err(TrainError::Config(message));
        }
        let shares = batch.split(devices.len());
        self.objective.geometry_weight = self.geometry_weight();
        let objective = &self.objective;
        let results = std::thread::scope(|scope| {
            let workers: Vec<_> = shares
                .into_iter()
                .zip(devices)
                .map(|(share, device)| {
                    let weight = share.reference.dims()[0] as f64 / items as f64;
                    let scaled = weight * self.scale();
                    let student = self.student.clone().fork(&device.clone().autodiff());
                    let teacher = self.teacher.clone().to_device(device);
                    let share = share.to_device(device);
                    scope.spawn(move || {
                        objective
                            .gradients(&teacher, &student, share, scaled)
                            .map(|(grads, values)| (grads, values, weight, student))
                    })
                })
                .collect();
            workers
                .into_iter()
                .zip(devices)
                .map(|(worker, device)| {
                    worker.join().unwrap_or_else(|_| {
                        Err(NetError::Device {
                            name: format!("{device:?}"),
                            reason: "its share of the step failed (the runtime panicked)".into(),
                        }
                        .into())
                    })
                })
                .collect::<Result<Vec<_>, _>>()
        })?;
        let home = devices[0].clone();
        let mut sum = GradientsAccumulator::<B>::new();
        let mut shares = Vec::with_capacity(results.len());
        for (grads, values, weight, replica) in results {
            sum.accumulate(&self.student, grads.to_device(&home, &replica));
            shares.push((values, weight));
        }
        self.apply(sum.grads(), LossValues::weighted_sum(&shares))
    }
}
