//! Where training and inference run: `cpu` (burn's flex backend), `vulkan`
//! (any Vulkan GPU through burn's wgpu backend, the opt-in `vulkan`
//! feature), `cuda` (an NVIDIA GPU through CubeCL's CUDA runtime, the `cuda`
//! feature). A comma-separated list names the devices of a data-parallel
//! run (see [`crate::S3Trainer::step_parallel`]).
//!
//! Opening a device runs a small kernel on it, so a missing driver, NVRTC or
//! CUDA headers are reported here as an error naming the device, instead of
//! as a panic in one of the runtime's threads at the first training step.

use std::fmt;
use std::panic::{self, AssertUnwindSafe};
use std::str::FromStr;
use std::sync::{Arc, Mutex, PoisonError};

use burn::tensor::{Device, Tensor};

use crate::error::NetError;

/// A device as named on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceName {
    /// burn's flex CPU backend (`cpu`).
    Cpu,
    /// A Vulkan adapter: the best one (`vulkan`) or the Nth discrete GPU
    /// (`vulkan:N`).
    Vulkan(Option<usize>),
    /// CUDA device N (`cuda` is `cuda:0`).
    Cuda(usize),
}

impl FromStr for DeviceName {
    type Err = NetError;

    fn from_str(name: &str) -> Result<Self, NetError> {
        let unknown = || NetError::Device {
            name: name.to_string(),
            reason: "unknown device: use cpu, vulkan, vulkan:N, cuda or cuda:N, or a \
                     comma-separated list of them (cuda:0,cuda:1)"
                .into(),
        };
        let (kind, index) = match name.split_once(':') {
            Some((kind, index)) => (kind, Some(index.parse().map_err(|_| unknown())?)),
            None => (name, None),
        };
        match (kind, index) {
            ("cpu", None) => Ok(Self::Cpu),
            ("vulkan", index) => Ok(Self::Vulkan(index)),
            ("cuda", index) => Ok(Self::Cuda(index.unwrap_or(0))),
            _ => Err(unknown()),
        }
    }
}

impl fmt::Display for DeviceName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Cpu => write!(f, "cpu"),
            Self::Vulkan(None) => write!(f, "vulkan"),
            Self::Vulkan(Some(index)) => write!(f, "vulkan:{index}"),
            Self::Cuda(index) => write!(f, "cuda:{index}"),
        }
    }
}

impl DeviceName {
    /// Opens the device and runs a small kernel on it. An error names the
    /// device and says what is missing: the build feature, the driver, or
    /// (for CUDA) NVRTC and the CUDA headers.
    pub fn open(self) -> Result<Device, NetError> {
        let failed = |reason: String| NetError::Device {
            name: self.to_string(),
            reason,
        };
        match self {
            Self::Cpu => Ok(Device::flex()),
            Self::Vulkan(index) => open_vulkan(index).map_err(failed),
            Self::Cuda(index) => open_cuda(index).map_err(failed),
        }
    }
}

/// Opens the one device `name` names (see [`DeviceName`]).
pub fn open_device(name: &str) -> Result<Device, NetError> {
    name.trim().parse::<DeviceName>()?.open()
}

/// The devices of a `--device` flag, parsed once: one device, or a
/// comma-separated list of them (data parallel), each remembered as
/// written (`cuda` names no GPU in particular, `cuda:0` does).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceList {
    /// Each device, and whether its index was written.
    devices: Vec<(DeviceName, bool)>,
}

impl FromStr for DeviceList {
    type Err = NetError;

    fn from_str(list: &str) -> Result<Self, NetError> {
        let devices = list
            .split(',')
            .map(|name| {
                let name = name.trim();
                Ok((name.parse()?, name.contains(':')))
            })
            .collect::<Result<_, NetError>>()?;
        Ok(Self { devices })
    }
}

impl fmt::Display for DeviceList {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, (name, indexed)) in self.devices.iter().enumerate() {
            let separator = if i == 0 { "" } else { "," };
            match (name, indexed) {
                (DeviceName::Cuda(_), false) => write!(f, "{separator}cuda")?,
                _ => write!(f, "{separator}{name}")?,
            }
        }
        Ok(())
    }
}

impl DeviceList {
    /// The devices' names, in order.
    pub fn names(&self) -> Vec<DeviceName> {
        self.devices.iter().map(|(name, _)| *name).collect()
    }

    /// The devices of one of several processes on a machine (the ranks
    /// of an MPI job) that were all given this list, whose `k` entries
    /// each rank takes alike: `cuda` and `vulkan` without an index become
    /// GPUs `k * local_rank` to `k * local_rank + k - 1`, in order (with
    /// one entry, GPU `local_rank`); a named device (`cpu`, `cuda:2`)
    /// stays as it is.
    pub fn of_rank(&self, local_rank: usize) -> DeviceList {
        let first = self.devices.len() * local_rank;
        let devices = self
            .devices
            .iter()
            .enumerate()
            .map(|(i, &(name, indexed))| {
                let name = match (name, indexed) {
                    (DeviceName::Cuda(_), false) => DeviceName::Cuda(first + i),
                    (DeviceName::Vulkan(None), _) => DeviceName::Vulkan(Some(first + i)),
                    _ => name,
                };
                (name, true)
            })
            .collect();
        DeviceList { devices }
    }

    /// Opens each device, in order ([`DeviceName::open`]). The same device
    /// may appear twice (its shares then run one after the other).
    pub fn open(&self) -> Result<Vec<Device>, NetError> {
        self.devices.iter().map(|(name, _)| name.open()).collect()
    }
}

#[cfg(feature = "vulkan")]
fn open_vulkan(index: Option<usize>) -> Result<Device, String> {
    use burn::tensor::DeviceKind;
    use burn::tensor::wgpu::WgpuBackend;

    // A wgpu runtime is initialised once per process; later opens reuse it.
    static OPENED: Mutex<Vec<(Option<usize>, Device)>> = Mutex::new(Vec::new());
    let mut opened = OPENED.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some((_, device)) = opened.iter().find(|(i, _)| *i == index) {
        return Ok(device.clone());
    }
    let kind = index.map_or(DeviceKind::DefaultDevice, DeviceKind::DiscreteGpu);
    // The driver and the loader's layers print to stderr while the device
    // opens (Mesa's device-select layer: "error: XDG_RUNTIME_DIR is invalid
    // or not set in the environment." on a machine without a desktop), so
    // what they print is held and passed on labelled as theirs. `None` when
    // stderr is already held elsewhere.
    let driver_output = gag::BufferRedirect::stderr().ok();
    let device = Device::wgpu_options()
        .graphics_api(WgpuBackend::Vulkan)
        .device_kind(kind)
        .init()
        .map_err(|e| {
            format!(
                "no usable Vulkan device ({e}); install the GPU's Vulkan driver, or Mesa's \
                 lavapipe to run on the CPU (Debian: apt-get install mesa-vulkan-drivers)"
            )
        })
        .and_then(|device| run_probe(&device).map(|()| device));
    if let Some(held) = driver_output {
        pass_on_driver_output(held);
    }
    let device = device?;
    opened.push((index, device.clone()));
    Ok(device)
}

/// Prints each distinct line the Vulkan driver printed while it was held,
/// once, as a note naming its source.
#[cfg(feature = "vulkan")]
fn pass_on_driver_output(mut held: gag::BufferRedirect) {
    use std::io::Read;

    let mut text = String::new();
    let read = held.read_to_string(&mut text);
    drop(held);
    if read.is_err() {
        return;
    }
    let mut seen = Vec::new();
    for line in text.lines().map(str::trim).filter(|line| !line.is_empty()) {
        if !seen.contains(&line) {
            eprintln!("note: the Vulkan driver printed: {line}");
            seen.push(line);
        }
    }
}

#[cfg(not(feature = "vulkan"))]
fn open_vulkan(_index: Option<usize>) -> Result<Device, String> {
    Err(missing_feature("vulkan"))
}

#[cfg(feature = "cuda")]
fn open_cuda(index: usize) -> Result<Device, String> {
    let device = Device::cuda(index);
    run_probe(&device).map_err(|reason| {
        // cudarc follows a missing library with every file name it tried.
        let reason = reason.split(" - searched for").next().unwrap_or_default();
        format!(
            "CUDA is not usable ({reason}); it needs the NVIDIA driver (libcuda), NVRTC \
             (libnvrtc) and the CUDA headers at run time"
        )
    })?;
    Ok(device)
}

#[cfg(not(feature = "cuda"))]
fn open_cuda(_index: usize) -> Result<Device, String> {
    Err(missing_feature("cuda"))
}

#[cfg(not(all(feature = "vulkan", feature = "cuda")))]
fn missing_feature(feature: &str) -> String {
    format!(
        "this build has no {feature} support: build with `cargo build --release -p mbs-tool \
         --features {feature}`"
    )
}

/// Runs a reduction on `device` and reads it back. GPU runtimes open their
/// device and compile kernels lazily, in threads of their own, and report a
/// failure there by panicking; the probe turns the first such panic into the
/// error's text and keeps it off the terminal.
#[cfg_attr(not(any(feature = "vulkan", feature = "cuda")), allow(dead_code))]
fn run_probe(device: &Device) -> Result<(), String> {
    let first_panic = Arc::new(Mutex::new(None::<String>));
    let recorded = Arc::clone(&first_panic);
    let previous_hook = panic::take_hook();
    panic::set_hook(Box::new(move |info| {
        let mut first = recorded.lock().unwrap_or_else(PoisonError::into_inner);
        if first.is_none() {
            let message = info
                .payload()
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| info.payload().downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "the runtime failed".into());
            *first = Some(message);
        }
    }));
    let result = panic::catch_unwind(AssertUnwindSafe(|| {
        Tensor::<1>::from_floats([1.0, 2.0, 3.0], device)
            .sum()
            .into_scalar::<f32>()
    }));
    panic::set_hook(previous_hook);
    let panicked = first_panic
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .take();
    match (result, panicked) {
        (Ok(6.0), None) => Ok(()),
        (Ok(sum), None) => Err(format!("a test reduction gave {sum} instead of 6")),
        (_, Some(message)) => Err(message.lines().next().unwrap_or_default().to_string()),
        (Err(_), None) => Err("the runtime failed".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_process_takes_the_gpus_of_its_local_rank_unless_they_are_named() {
        let devices_of_rank = |list: &str, rank| {
            let list: DeviceList = list.parse().expect("known devices");
            list.of_rank(rank).to_string()
        };
        assert_eq!(devices_of_rank("cuda", 3), "cuda:3");
        assert_eq!(devices_of_rank(" vulkan ", 1), "vulkan:1");
        assert_eq!(devices_of_rank("cuda:0", 3), "cuda:0");
        assert_eq!(devices_of_rank("cpu", 2), "cpu");
        // A list of k: each rank takes the next k GPUs, named ones as given.
        assert_eq!(devices_of_rank("cuda,cuda", 1), "cuda:2,cuda:3");
        assert_eq!(devices_of_rank("cuda:0,cuda:1", 1), "cuda:0,cuda:1");
        assert_eq!(devices_of_rank("cpu,vulkan", 1), "cpu,vulkan:3");
        let list: DeviceList = "cuda, cuda:1,vulkan".parse().expect("known devices");
        assert_eq!(list.to_string(), "cuda,cuda:1,vulkan");
        assert_eq!(
            list.names(),
            [
                DeviceName::Cuda(0),
                DeviceName::Cuda(1),
                DeviceName::Vulkan(None)
            ]
        );
    }

    #[test]
    fn names_are_parsed_printed_and_unknown_ones_refused() {
        for (text, name) in [
            ("cpu", DeviceName::Cpu),
            ("vulkan", DeviceName::Vulkan(None)),
            ("vulkan:1", DeviceName::Vulkan(Some(1))),
            ("cuda", DeviceName::Cuda(0)),
            ("cuda:3", DeviceName::Cuda(3)),
        ] {
            assert_eq!(text.parse::<DeviceName>().ok(), Some(name), "{text}");
        }
        assert_eq!(DeviceName::Cuda(0).to_string(), "cuda:0");
        assert_eq!(DeviceName::Vulkan(Some(2)).to_string(), "vulkan:2");
        for bad in ["tpu", "cuda3", "cuda:x", "cpu:1", ""] {
            let message = open_device(bad).expect_err(bad).to_string();
            assert!(message.contains("unknown device"), "{bad}: {message}");
        }
        assert_eq!(
            "cpu, cpu"
                .parse::<DeviceList>()
                .and_then(|l| l.open())
                .map(|d| d.len())
                .ok(),
            Some(2)
        );
        #[cfg(not(feature = "cuda"))]
        {
            let message = open_device("cuda:1")
                .expect_err("no CUDA build")
                .to_string();
            assert!(message.starts_with("device `cuda:1`"), "{message}");
            assert!(message.contains("--features cuda"), "{message}");
        }
    }
}
