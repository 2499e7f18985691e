//! ONNX Runtime flags shared by the commands that run ONNX models.

use std::path::PathBuf;

use mbs_infer::onnx::{Device, RuntimeOptions};

/// Where and with which library ONNX models run.
#[derive(clap::Args, Debug, Clone)]
pub struct OnnxArgs {
    /// Execution device of ONNX models: cpu, cuda (GPU 0) or cuda:N. CUDA
    /// needs a build with `--features cuda` and the onnxruntime-gpu library
    /// (tools/setup-ort.sh --gpu).
    #[arg(long, default_value = "cpu", value_parser = parse_device)]
    pub device: Device,
    /// The ONNX Runtime library [default: $ORT_DYLIB_PATH, then
    /// .ort/onnxruntime/capi/libonnxruntime.so.* above the current folder or
    /// the executable, installed by tools/setup-ort.sh].
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
    /// Run on the CPU when --device cannot be used, instead of failing.
    #[arg(long)]
    pub allow_cpu_fallback: bool,
}

fn parse_device(s: &str) -> Result<Device, String> {
    s.parse()
}

impl OnnxArgs {
    /// The runtime options these flags ask for.
    pub fn options(&self) -> RuntimeOptions {
        RuntimeOptions {
            library: self.ort_lib.clone(),
            device: self.device,
            allow_cpu_fallback: self.allow_cpu_fallback,
            intra_threads: 0,
        }
    }

    /// Says on stderr when a model fell back to the CPU.
    pub fn report_fallback(&self, what: &str, used: Device) {
        if used != self.device {
            eprintln!(
                "warning: {what}: device {} is not available, running on {used} (--allow-cpu-fallback)",
                self.device
            );
        }
    }
}
