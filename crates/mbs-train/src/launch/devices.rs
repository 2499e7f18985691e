//! The devices of one process of a run, opened under one consensus: a
//! device that fails on one rank fails the launch on every rank alike.

use burn::tensor::Device;
use mbs_nets::device::{DeviceList, DeviceName};

use crate::distributed::{Collective, all_succeeded};
use crate::error::TrainError;

/// The devices of this process, each with its name, opened: the whole of
/// `list` for a process of its own; for a rank of `processes`, its part
/// ([`DeviceList::of_rank`]: with `k` devices, the rank takes GPUs `k *
/// local_rank` to `k * local_rank + k - 1` for those without an index,
/// and a named device stays as it is), opened on every rank before any
/// goes on.
pub(super) fn open(
    list: &DeviceList,
    processes: Option<&dyn Collective>,
) -> Result<(Vec<DeviceName>, Vec<Device>), TrainError> {
    let Some(processes) = processes else {
        return Ok((list.names(), list.open()?));
    };
    let mine = list.of_rank(processes.local_rank());
    let opened = all_succeeded(processes, mine.open())?;
    Ok((mine.names(), opened))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rank_takes_its_own_gpus_and_named_devices_as_written() {
        let of = |list: &str, rank| {
            let list: DeviceList = list.parse().expect("a list");
            let mine = list.of_rank(rank);
            mine.names()
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
        };
        assert_eq!(of("cuda", 3), ["cuda:3"]);
        assert_eq!(of("cuda,cuda", 1), ["cuda:2", "cuda:3"]);
        assert_eq!(of("vulkan,vulkan", 0), ["vulkan:0", "vulkan:1"]);
        assert_eq!(of("cpu,cpu", 1), ["cpu", "cpu"]);
        assert_eq!(of("cuda:0,cuda:5", 1), ["cuda:0", "cuda:5"]);
    }
}
