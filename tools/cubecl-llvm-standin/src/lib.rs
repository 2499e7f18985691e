//! The part of cubecl-llvm's interface that cubecl-cuda names, with no LLVM
//! behind it. cubecl-cuda picks its CUDA C++ (NVRTC) compiler when the
//! `cubecl/cuda-cpp` feature is on, as mbs's `cuda` feature does, so the LLVM
//! compiler here is never constructed; if it were, compiling a kernel returns
//! an error that says so instead of producing PTX.

use cubecl_core::ir::DeviceProperties;
use cubecl_core::ir::nvidia::SmArch;
use cubecl_core::prelude::KernelDefinition;
use cubecl_environment::backtrace::BackTrace;
use cubecl_runtime::compiler::CompilationError;
use cubecl_runtime::kernel::BufferIOAttr;

/// The targets the real crate lowers to; only NVPTX is named by cubecl-cuda.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LlvmTarget {
    /// NVIDIA's PTX.
    #[default]
    Nvptx,
}

/// Options of the LLVM compiler, with the fields cubecl-cuda sets.
#[derive(Clone, Debug, Default)]
pub struct PlironOptions {
    /// AMD architecture in the real crate; always `None` for CUDA.
    pub arch: Option<()>,
    /// The NVIDIA architecture.
    pub sm_arch: Option<SmArch>,
    /// The PTX version to emit.
    pub ptx_version: Option<nvptx::ptx_version::PtxVersion>,
    /// Whether scalars travel in the kernel parameter block.
    pub grid_constants: bool,
}

/// A compiled PTX module, as cubecl-cuda reads it.
#[derive(Clone, Debug)]
pub struct NvptxModule {
    /// NUL-terminated PTX assembly.
    pub ptx: Vec<std::ffi::c_char>,
    /// The kernel's entry point.
    pub entrypoint: String,
    /// The IR, for logs and cache keys.
    pub ir: String,
    /// Dynamic shared memory per launch, in bytes.
    pub shared_memory_size: usize,
    /// How each buffer binding is accessed.
    pub io: Vec<BufferIOAttr>,
}

/// What the LLVM compiler produces.
#[derive(Debug)]
pub enum PlironArtifact {
    /// A PTX module.
    NvptxCode(NvptxModule),
}

/// The LLVM kernel compiler; this stand-in refuses every kernel.
#[derive(Clone, Debug, Default)]
pub struct PlironCompiler {
    /// The target it would lower to.
    pub target: LlvmTarget,
}

impl PlironCompiler {
    /// The language of the IR it would log.
    pub fn lang_tag(&self) -> &'static str {
        "llvm"
    }

    /// Always an error: this build compiles CUDA kernels through NVRTC only.
    pub fn compile(
        &mut self,
        _kernel: KernelDefinition,
        _options: &PlironOptions,
    ) -> Result<PlironArtifact, CompilationError> {
        Err(CompilationError::Generic {
            reason: "this build has no LLVM kernel compiler (mbs's offline cubecl-llvm \
                     stand-in); CUDA kernels compile as C++ through NVRTC"
                .to_string(),
            backtrace: BackTrace::capture(),
        })
    }
}

/// NVPTX-specific items.
pub mod nvptx {
    /// The PTX ISA version.
    pub mod ptx_version {
        use std::fmt;

        /// A PTX ISA version, major * 10 + minor (8.7 is 87).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub struct PtxVersion(u32);

        /// The first driver version (as `cuDriverGetVersion` reports it, 12.8
        /// is 12080) of each PTX ISA version, newest first: NVIDIA's PTX ISA
        /// release notes.
        const FIRST_DRIVER: [(i32, u32); 6] = [
            (12080, 87),
            (12040, 84),
            (12000, 80),
            (11080, 78),
            (11000, 70),
            (10000, 63),
        ];

        impl PtxVersion {
            /// The newest version a driver loads; `None` before CUDA 10.
            pub fn for_driver(driver: i32) -> Option<Self> {
                FIRST_DRIVER
                    .iter()
                    .find(|(first, _)| driver >= *first)
                    .map(|&(_, version)| Self(version))
            }
        }

        impl fmt::Display for PtxVersion {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "ptx{}", self.0)
            }
        }
    }
}

/// Items shared by the GPU targets.
pub mod shared {
    /// Device properties narrowed to what the LLVM compiler lowers.
    pub mod lowered_features {
        use super::super::DeviceProperties;

        /// The GPU a device's properties would be narrowed for.
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum GpuTarget {
            /// NVIDIA.
            Nvptx,
        }

        /// Leaves the properties as they are: with no LLVM compiler, the
        /// NVRTC compiler's properties stand (cubecl-cuda calls this only
        /// when it compiles through LLVM).
        pub fn restrict_features(_properties: &mut DeviceProperties, _target: GpuTarget) {}
    }
}
