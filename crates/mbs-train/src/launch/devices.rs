//! The devices of one process of a run, opened under one consensus: a
//! device that fails on one rank fails the launch on every rank alike.

use burn::tensor::Device;
use mbs_nets::device::{DeviceList, DeviceName};

use crate::distributed::{Collective, all_succeeded};
use crate::error::TrainError;

/// The devices of this process, each with its name, opened: the whole of
/// `list` for a process of its own; for a rank of `processes`, its part
/// (see [`rank_devices`]), opened on every rank before any goes on.
pub(super) fn open(
    list: &DeviceList,
    processes: Option<&dyn Collective>,
) -> Result<(Vec<DeviceName>, Vec<Device>), TrainError> {
    let Some(processes) = processes else {
        return Ok((list.names(), list.open()?));
    };
    let opened = rank_devices(list, processes.local_rank()).and_then(|mine| {
        let devices = mine
            .iter()
            .map(DeviceList::open)
            .collect::<Result<Vec<_>, _>>();
        Ok((mine, devices?))
    });
    let outcome = opened.as_ref().map(drop).map_err(ToString::to_string);
    all_succeeded(processes, outcome)?;
    let (mine, devices) = opened?;
    let names = mine.iter().flat_map(DeviceList::names).collect();
    Ok((names, devices.into_iter().flatten().collect()))
}

/// The devices of the rank `local_rank` on its machine, when every rank
/// there was given `list`, each as a list of one: with one device, `cuda`
/// and `vulkan` without an index mean GPU `local_rank`
/// ([`DeviceList::of_process`]); with `k` devices, the rank takes GPUs `k *
/// local_rank` to `k * local_rank + k - 1` for those without an index,
/// and a named device (`cpu`, `cuda:2`) stays as it is.
fn rank_devices(list: &DeviceList, local_rank: usize) -> Result<Vec<DeviceList>, TrainError> {
    // The list as written, one device at a time (its text keeps whether
    // an index was given, which the parsed names do not).
    let parts = list
        .to_string()
        .split(',')
        .map(str::parse::<DeviceList>)
        .collect::<Result<Vec<_>, _>>()?;
    let count = parts.len();
    let mine = parts
        .iter()
        .enumerate()
        .map(|(i, part)| part.of_process(count * local_rank + i))
        .collect::<Result<_, _>>()?;
    Ok(mine)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rank_takes_its_own_gpus_and_named_devices_as_written() {
        let of = |list: &str, rank| {
            let list: DeviceList = list.parse().expect("a list");
            let mine = rank_devices(&list, rank).expect("devices");
            mine.iter().map(ToString::to_string).collect::<Vec<_>>()
        };
        assert_eq!(of("cuda", 3), ["cuda:3"]);
        assert_eq!(of("cuda,cuda", 1), ["cuda:2", "cuda:3"]);
        assert_eq!(of("vulkan,vulkan", 0), ["vulkan:0", "vulkan:1"]);
        assert_eq!(of("cpu,cpu", 1), ["cpu", "cpu"]);
        assert_eq!(of("cuda:0,cuda:5", 1), ["cuda:0", "cuda:5"]);
    }
}
