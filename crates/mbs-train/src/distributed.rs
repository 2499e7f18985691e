//! Training spread over several processes (the ranks of an MPI job): what
//! a run needs from the engine that connects them ([`Collective`]), the
//! gradients as one flat buffer for its all-reduce ([`FlatGradients`]),
//! and the checks that keep the ranks in step: the same settings and files
//! at the start ([`agree`]), the same weights while training
//! ([`check_same_weights`]).
//!
//! The engine itself (MPI) lives in `mbs-mpi`, behind a cargo feature, so
//! that this crate and the default build need nothing but Rust.

use std::hash::{DefaultHasher, Hasher};

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::GradientsParams;
use burn::tensor::{Device, Tensor, TensorData};
use serde_json::Value;

use crate::error::TrainError;
use mbs_nets::host::read_all;

/// The processes of one data-parallel run, as an MPI communicator sees
/// them. Every call is collective: each process makes the same calls in
/// the same order, and each returns once all have made it.
pub trait Collective {
    /// This process's index, 0 to `size() - 1`; rank 0 writes the run's files.
    fn rank(&self) -> usize;
    /// The number of processes.
    fn size(&self) -> usize;
    /// This process's index among those on its machine: the GPU it takes
    /// when the device names none.
    fn local_rank(&self) -> usize;
    /// Ends every process with exit code `code`: for an error only this
    /// process met while the others wait for it in a collective call.
    fn abort(&self, code: i32) -> !;
    /// The element-wise sum over all processes of each one's `values` (the
    /// buffers have the same length everywhere). Taking the buffer lets an
    /// engine without an in-place sum keep it as the next call's receive
    /// buffer instead of copying it.
    fn sum(&self, values: Vec<f32>) -> Vec<f32>;
    /// Every process's `bytes`, in rank order, on every process.
    fn gather(&self, bytes: &[u8]) -> Vec<Vec<u8>>;
}

/// Checks that every rank holds the same `what` (a JSON object: settings,
/// file digests, the checkpoint found): an error on every rank, naming the
/// first key that differs and the ranks' values, when one does not. Runs
/// before a rank writes anything.
pub fn agree(collective: &dyn Collective, what: &Value) -> Result<(), TrainError> {
    let mine = serde_json::to_vec(what).map_err(|e| TrainError::Config(e.to_string()))?;
    let all = collective.gather(&mine);
    let parsed = all
        .iter()
        .map(|bytes| serde_json::from_slice::<Value>(bytes))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| TrainError::Distributed(format!("a rank sent unreadable settings: {e}")))?;
    let first = &parsed[0];
    for (rank, other) in parsed.iter().enumerate().skip(1) {
        if let Some((key, here, there)) = first_difference("", first, other) {
            return Err(TrainError::Distributed(format!(
                "the ranks disagree before the first step: {key} is {there} on rank {rank} \
                 and {here} on rank 0; every rank must run the same command on the same files \
                 (nothing was written)"
            )));
        }
    }
    Ok(())
}

/// Turns an outcome that may differ between ranks (opening this rank's
/// device) into one every rank shares: this rank's value when it
/// succeeded everywhere, else an error on every rank naming the first
/// rank that failed and why.
pub fn all_succeeded<T, E: std::fmt::Display>(
    collective: &dyn Collective,
    outcome: Result<T, E>,
) -> Result<T, TrainError> {
    let mine = match &outcome {
        Ok(_) => Vec::new(),
        Err(error) => error.to_string().into_bytes(),
    };
    let all = collective.gather(&mine);
    match all.iter().position(|bytes| !bytes.is_empty()) {
        None => outcome.map_err(|e| TrainError::Distributed(e.to_string())),
        Some(rank) => Err(TrainError::Distributed(format!(
            "rank {rank} of {}: {}",
            all.len(),
            String::from_utf8_lossy(&all[rank])
        ))),
    }
}

/// The first key (dotted path) at which `a` and `b` differ, with both
/// values; `None` when they are equal.
fn first_difference(path: &str, a: &Value, b: &Value) -> Option<(String, String, String)> {
    let join = |key: &str| match path {
        "" => key.to_string(),
        _ => format!("{path}.{key}"),
    };
    match (a, b) {
        (Value::Object(a_map), Value::Object(b_map)) => {
            let keys: std::collections::BTreeSet<&String> =
                a_map.keys().chain(b_map.keys()).collect();
            keys.into_iter().find_map(|key| {
                let missing = Value::String("(not set)".into());
                let (x, y) = (
                    a_map.get(key).unwrap_or(&missing),
                    b_map.get(key).unwrap_or(&missing),
                );
                first_difference(&join(key), x, y)
            })
        }
        _ if a == b => None,
        _ => Some((
            if path.is_empty() {
                "the settings".into()
            } else {
                path.into()
            },
            a.to_string(),
            b.to_string(),
        )),
    }
}

/// Checks that every rank's `networks` (e.g. student and teacher) hold
/// bit-identical weights after `steps` steps; an error on every rank when
/// one does not, since the ranks would train different networks from then
/// on. Costs one read of the weights and one small gather.
pub fn check_same_weights<M: Module>(
    collective: &dyn Collective,
    networks: &[&M],
    steps: usize,
) -> Result<(), TrainError> {
    let mut digest = Digest::default();
    for network in networks {
        network.visit(&mut digest);
    }
    let mine = digest.hasher.finish().to_le_bytes();
    let all = collective.gather(&mine);
    if let Some(rank) = all.iter().position(|other| other[..] != mine[..]) {
        return Err(TrainError::Distributed(format!(
            "the ranks' weights differ after step {steps} (rank {rank}'s from rank {}'s): \
             the processes no longer train the same network. Check that every rank runs the \
             same binary on the same kind of device, then resume from the last checkpoint",
            collective.rank()
        )));
    }
    Ok(())
}

/// Hashes the bytes of every float parameter, in visiting order.
#[derive(Default)]
struct Digest {
    hasher: DefaultHasher,
}

impl ModuleVisitor for Digest {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let data = param.val().into_data();
        self.hasher.write(data.bytes());
    }
}

/// The gradients of a module's parameters as one host buffer (in the
/// module's visiting order), for an all-reduce in one call instead of one
/// per parameter.
#[derive(Debug, Clone)]
pub struct FlatGradients {
    /// The gradients, each flattened, one after another.
    pub values: Vec<f32>,
    /// For each parameter with a gradient: its id, shape and start in `values`.
    layout: Vec<(burn::module::ParamId, Vec<usize>, usize)>,
    device: Device,
}

impl FlatGradients {
    /// Copies the gradients of `module`'s float parameters out of `grads`
    /// (concatenated on their device, read back once).
    pub fn gather<M: Module>(module: &M, grads: &GradientsParams) -> Result<Self, TrainError> {
        let mut collect = Collect {
            grads,
            parts: Vec::new(),
            layout: Vec::new(),
            length: 0,
        };
        module.visit(&mut collect);
        let Collect { parts, layout, .. } = collect;
        let Some(device) = parts.first().map(Tensor::device) else {
            return Err(TrainError::Shape("the module has no gradient".into()));
        };
        let values = read_all(Tensor::cat(parts, 0), "the gradients")?;
        Ok(Self {
            values,
            layout,
            device,
        })
    }

    /// Replaces the values by their sum over `collective`'s processes.
    pub fn sum_over(&mut self, collective: &dyn Collective) {
        self.values = collective.sum(std::mem::take(&mut self.values));
    }

    /// The gradients back on their device, as the optimiser takes them.
    pub fn into_grads(self) -> GradientsParams {
        let total = self.values.len();
        let all = Tensor::<1>::from_data(TensorData::new(self.values, [total]), &self.device);
        let mut grads = GradientsParams::new();
        for (id, shape, start) in self.layout {
            let size = shape.iter().product();
            let part = all.clone().narrow(0, start, size);
            match shape.len() {
                1 => grads.register(id, part),
                2 => grads.register(id, part.reshape(dims::<2>(&shape))),
                3 => grads.register(id, part.reshape(dims::<3>(&shape))),
                4 => grads.register(id, part.reshape(dims::<4>(&shape))),
                _ => grads.register(id, part.reshape(dims::<5>(&shape))),
            }
        }
        grads
    }
}

fn dims<const D: usize>(shape: &[usize]) -> [usize; D] {
    let mut out = [1; D];
    out.copy_from_slice(&shape[..D]);
    out
}

/// The number of gradient values `grads` holds for `module`'s float
/// parameters (those with a gradient), counted from their shapes without
/// reading them: the length of their [`FlatGradients`].
pub fn gradient_length<M: Module>(module: &M, grads: &GradientsParams) -> usize {
    let mut count = Count { grads, length: 0 };
    module.visit(&mut count);
    count.length
}

/// Counts the gradient values of the parameters it visits.
struct Count<'a> {
    grads: &'a GradientsParams,
    length: usize,
}

impl ModuleVisitor for Count<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(grad) = self.grads.get::<D>(param.id) {
            self.length += grad.dims().iter().product::<usize>();
        }
    }
}

/// Flattens the gradients of the parameters it visits.
struct Collect<'a> {
    grads: &'a GradientsParams,
    parts: Vec<Tensor<1>>,
    layout: Vec<(burn::module::ParamId, Vec<usize>, usize)>,
    length: usize,
}

impl ModuleVisitor for Collect<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(grad) = self.grads.get::<D>(param.id) {
            let shape = grad.dims().to_vec();
            let size: usize = shape.iter().product();
            self.layout.push((param.id, shape, self.length));
            self.length += size;
            self.parts.push(grad.reshape([size]));
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::sync::{Arc, Barrier, Mutex};

    use burn::nn::{Linear, LinearConfig};
    use mbs_nets::test_util::values;
    use serde_json::json;

    /// Processes simulated by threads that meet at a barrier: the
    /// [`Collective`] contract without an MPI installation.
    pub(crate) struct Threads {
        rank: usize,
        shared: Arc<(Barrier, Mutex<Vec<Vec<u8>>>)>,
    }

    impl Threads {
        pub(crate) fn group(size: usize) -> Vec<Threads> {
            let shared = Arc::new((Barrier::new(size), Mutex::new(vec![Vec::new(); size])));
            (0..size)
                .map(|rank| Threads {
                    rank,
                    shared: Arc::clone(&shared),
                })
                .collect()
        }
    }

    impl Collective for Threads {
        fn rank(&self) -> usize {
            self.rank
        }
        fn size(&self) -> usize {
            self.shared.1.lock().expect("lock").len()
        }
        fn local_rank(&self) -> usize {
            self.rank
        }
        fn abort(&self, code: i32) -> ! {
            panic!("rank {} aborted with {code}", self.rank)
        }
        fn sum(&self, values: Vec<f32>) -> Vec<f32> {
            let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
            let all = self.gather(&bytes);
            (0..values.len())
                .map(|i| {
                    all.iter()
                        .map(|b| f32::from_le_bytes(b[4 * i..4 * i + 4].try_into().expect("4")))
                        .sum()
                })
                .collect()
        }
        fn gather(&self, bytes: &[u8]) -> Vec<Vec<u8>> {
            let (barrier, slots) = &*self.shared;
            slots.lock().expect("lock")[self.rank] = bytes.to_vec();
            barrier.wait();
            let all = slots.lock().expect("lock").clone();
            barrier.wait();
            all
        }
    }

    fn on_ranks<T: Send>(size: usize, work: impl Fn(&Threads) -> T + Sync) -> Vec<T> {
        let group = Threads::group(size);
        std::thread::scope(|scope| {
            let handles: Vec<_> = group
                .iter()
                .map(|rank| scope.spawn(|| work(rank)))
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("rank"))
                .collect()
        })
    }

    #[test]
    fn agreeing_ranks_pass_and_a_difference_is_named_on_every_rank() {
        let same = on_ranks(3, |rank| agree(rank, &json!({"settings": {"seed": 1}})));
        assert!(same.iter().all(Result::is_ok), "{same:?}");
        let differ = on_ranks(3, |rank| {
            let lr = if rank.rank() == 2 { 1e-3 } else { 2e-4 };
            agree(
                rank,
                &json!({"settings": {"trainer": {"lr": {"max_lr": lr}}, "seed": 1}}),
            )
        });
        for result in differ {
            let message = result.expect_err("refused").to_string();
            assert!(
                message
                    .contains("settings.trainer.lr.max_lr is 0.001 on rank 2 and 0.0002 on rank 0"),
                "{message}"
            );
        }
        let missing = on_ranks(2, |rank| match rank.rank() {
            0 => agree(rank, &json!({"checkpoint": 40})),
            _ => agree(rank, &json!({})),
        });
        let message = missing[1].as_ref().expect_err("refused").to_string();
        assert!(
            message.contains("checkpoint is \"(not set)\" on rank 1 and 40 on rank 0"),
            "{message}"
        );
    }

    #[test]
    fn one_rank_failing_fails_every_rank_with_its_reason() {
        let fine = on_ranks(2, |rank| all_succeeded(rank, Ok::<(), String>(())));
        assert!(fine.iter().all(Result::is_ok), "{fine:?}");
        let one_fails = on_ranks(3, |rank| match rank.rank() {
            1 => all_succeeded(rank, Err::<(), String>("cuda:1: no such device".into())),
            _ => all_succeeded(rank, Ok::<(), String>(())),
        });
        for result in one_fails {
            let message = result.expect_err("refused").to_string();
            assert_eq!(message, "rank 1 of 3: cuda:1: no such device");
        }
    }

    #[test]
    fn weights_that_differ_are_refused_on_every_rank() {
        let device = Device::flex();
        device.seed(3);
        let layer = LinearConfig::new(3, 2).init(&device);
        let other = LinearConfig::new(3, 2).init(&device);
        let same = on_ranks(2, |rank| check_same_weights(rank, &[&layer], 7));
        assert!(same.iter().all(Result::is_ok), "{same:?}");
        let differ = on_ranks(2, |rank| {
            let mine = if rank.rank() == 0 { &layer } else { &other };
            check_same_weights(rank, &[mine], 7)
        });
        for result in differ {
            let message = result.expect_err("refused").to_string();
            assert!(message.contains("weights differ after step 7"), "{message}");
        }
    }

    /// Gathered, summed over ranks and put back, each parameter's gradient
    /// is the sum of the ranks' gradients of that parameter, in its shape.
    #[test]
    fn flat_gradients_round_trip_and_sum_per_parameter() {
        let device = Device::flex().autodiff();
        let layer: Linear = LinearConfig::new(3, 2).init(&device);
        let inner = device.clone().inner();
        let grads_of_rank = |rank: usize| {
            let scale = (rank + 1) as f32;
            let mut grads = GradientsParams::new();
            let weight: Vec<f32> = (0..6).map(|i| scale * i as f32).collect();
            grads.register(
                layer.weight.id,
                Tensor::<2>::from_data(TensorData::new(weight, [3, 2]), &inner),
            );
            grads.register(
                layer.bias.as_ref().expect("bias").id,
                Tensor::<1>::from_data(TensorData::new(vec![scale, -scale], [2]), &inner),
            );
            grads
        };
        let summed = on_ranks(2, |rank| {
            let mut flat =
                FlatGradients::gather(&layer, &grads_of_rank(rank.rank())).expect("flat");
            assert_eq!(flat.values.len(), 8);
            flat.sum_over(rank);
            let grads = flat.into_grads();
            let weight = grads.get::<2>(layer.weight.id).expect("weight");
            assert_eq!(weight.dims(), [3, 2]);
            let bias = grads
                .get::<1>(layer.bias.as_ref().expect("bias").id)
                .expect("bias");
            (values(weight), values(bias))
        });
        for (weight, bias) in summed {
            assert_eq!(weight, (0..6).map(|i| 3.0 * i as f32).collect::<Vec<_>>());
            assert_eq!(bias, vec![3.0, -3.0]);
        }
    }
}
