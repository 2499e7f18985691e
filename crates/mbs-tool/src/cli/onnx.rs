//! ONNX Runtime flags shared by the commands that run ONNX models.

use std::path::PathBuf;

use mbs_infer::onnx::{Device, RuntimeOptions};
use mbs_nets::device::DeviceName;

/// Where and with which library ONNX models run.
#[derive(clap::Args, Debug, Clone)]
pub struct OnnxArgs {
    /// Where networks run: cpu, cuda (GPU 0) or cuda:N for ONNX models and
    /// trained networks, vulkan[:N] for trained networks (--checkpoint,
    /// --weights). CUDA needs a build with `--features cuda`, and for ONNX
    /// models the onnxruntime-gpu library (tools/setup-ort.sh --gpu).
    #[arg(long, default_value = "cpu", value_parser = crate::cli::values::device)]
    pub device: DeviceName,
    /// The ONNX Runtime library [default: $ORT_DYLIB_PATH, then
    /// .ort/onnxruntime/capi/libonnxruntime.so.* above the current folder or
    /// the executable, installed by tools/setup-ort.sh].
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
    /// Run on the CPU when --device cannot be used, instead of failing.
    #[arg(long)]
    pub allow_cpu_fallback: bool,
}

impl OnnxArgs {
    /// The device of ONNX models.
    fn onnx_device(&self) -> anyhow::Result<Device> {
        match self.device {
            DeviceName::Cpu => Ok(Device::Cpu),
            DeviceName::Cuda(index) => u32::try_from(index)
                .map(Device::Cuda)
                .map_err(|_| anyhow::anyhow!("--device {}: no such CUDA device", self.device)),
            DeviceName::Vulkan(_) => anyhow::bail!(
                "--device {}: ONNX models run on cpu or cuda; vulkan is for trained networks",
                self.device
            ),
        }
    }

    /// The runtime options these flags ask for.
    pub fn options(&self) -> anyhow::Result<RuntimeOptions> {
        Ok(RuntimeOptions {
            library: self.ort_lib.clone(),
            device: self.onnx_device()?,
            allow_cpu_fallback: self.allow_cpu_fallback,
            intra_threads: 0,
        })
    }

    /// Says on stderr when a model fell back to the CPU.
    pub fn report_fallback(&self, what: &str, used: Device) {
        if self.onnx_device().is_ok_and(|asked| asked != used) {
            eprintln!(
                "warning: {what}: device {} is not available, running on {used} (--allow-cpu-fallback)",
                self.device
            );
        }
    }
}
