//! Data parallel over MPI ranks: each rank computes its share's
//! gradients, the ranks exchange their loss values ([`super::wire`]) and
//! sum their gradients in one all-reduce, and each steps identically.

use super::objective::LossValues;
use super::{S3Trainer, StepReport, unshareable};
use crate::data::StepBatch;
use crate::distributed::{Collective, FlatGradients};
use crate::error::TrainError;
use mbs_nets::Backbone;

impl<B: Backbone> S3Trainer<B> {
    /// Takes this process's part of one optimisation step of a run spread
    /// over the processes of `collective` (MPI ranks), each holding the
    /// same weights: rank r holds share r of the step's `items` items
    /// (`share`, as [`mbs_batch::share`] deals them; each rank loads only
    /// its own, [`mbs_batch::load_share`]) and computes the gradient of its
    /// loss weighted by its share of the items, the ranks sum their
    /// gradients in one all-reduce of a flat buffer, and each clips, steps
    /// the optimiser and updates its teacher identically, so the weights
    /// stay the same everywhere (see
    /// [`crate::distributed::check_same_weights`]). The report is the
    /// whole batch's, on every rank.
    pub fn step_distributed(
        &mut self,
        share: StepBatch,
        items: usize,
        collective: &dyn Collective,
    ) -> Result<StepReport, TrainError> {
        let ranks = collective.size();
        if let Some(message) = unshareable(items, ranks, "processes") {
            return Err(TrainError::Distributed(message));
        }
        let weight = share.reference.dims()[0] as f64 / items as f64;
        self.objective.geometry_weight = self.geometry_weight();
        let (grads, values) =
            self.objective
                .gradients(&self.teacher, &self.student, share, weight * self.scale())?;
        let mut flat = FlatGradients::gather(&self.student, &grads)?;
        // The shares' loss values, and the gradient lengths, which must
        // agree before the buffers are summed.
        let mine = values.encode(weight, flat.values.len());
        let shares = collective
            .gather(&mine)
            .iter()
            .map(|bytes| LossValues::decode(bytes))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| TrainError::Distributed("a rank sent unreadable loss values".into()))?;
        if let Some(rank) = shares
            .iter()
            .position(|(_, _, len)| *len != flat.values.len())
        {
            return Err(TrainError::Distributed(format!(
                "rank {rank} computed {} gradient values where rank {} computed {}: the \
                 processes do not train the same network",
                shares[rank].2,
                collective.rank(),
                flat.values.len()
            )));
        }
        flat.sum_over(collective);
        let shares: Vec<_> = shares.into_iter().map(|(v, w, _)| (v, w)).collect();
        self.apply(flat.into_grads(), LossValues::weighted_sum(&shares))
    }
}
