//! The `mbs-tool` command line: a thin layer over the mbs library crates, one
//! module per subcommand, no algorithms here.

mod cli;
mod commands;

use clap::{Parser, Subcommand};

/// mimalloc keeps freed memory for reuse; glibc's allocator hands every
/// large freed tensor back to the kernel, which made a training step about
/// a third slower (BENCHMARKS.md).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Multi-baseline stereo toolkit: build training data for stereo networks
/// (CARLA depth decoding, synthetic scenes, novel-view extrapolation of stereo
/// pairs), match and score stereo pairs, and check datasets.
#[derive(Parser)]
#[command(name = "mbs-tool", version, propagate_version = true)]
#[command(after_help = "Start with `mbs-tool demo`, then `mbs-tool <COMMAND> --help`.")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the whole pipeline on built-in synthetic data and show the outputs.
    Demo(commands::demo::Args),
    /// Render synthetic multi-camera street scenes with exact ground truth.
    Synth(commands::synth::Args),
    /// Decode CARLA depth PNGs into metric depth and disparity maps.
    DecodeDepth(commands::decode_depth::Args),
    /// Score predicted disparities against ground truth (EPE, Out-x, D1).
    Eval(commands::eval::Args),
    /// Score one disparity source on several benchmarks at once (the paper's zero-shot table).
    Benchmark(commands::benchmark::Args),
    /// Predict a benchmark's test folder into the files its server accepts (KITTI, Middlebury, ETH3D).
    Submit(commands::submit::Args),
    /// Compute disparity for rectified pairs (built-in matcher or an ONNX network).
    Predict(commands::predict::Args),
    /// Synthesise two extra views of stereo pairs (one baseline further left and right).
    Extrapolate(commands::extrapolate::Args),
    /// Make multi-baseline sets from single photos through a monocular depth network.
    Mono(commands::mono::Args),
    /// Scan an MBS20K folder into a manifest and print its statistics.
    Scan(commands::scan::Args),
    /// Check a dataset manifest against its schema and the files on disk.
    Validate(commands::validate::Args),
    /// Train a stereo network without ground truth (S3 teacher-student).
    Train(commands::train::Args),
    /// Write a training run's network as safetensors with the official keys.
    Export(commands::export::Args),
}

/// burn's default device, where it places what it creates without being
/// given a device. burn picks a GPU backend by default when one is built
/// in (Vulkan is), and so a CPU `train` that resumed (burn restores the
/// optimizer's state there before moving it to each parameter's device)
/// probed every Vulkan driver, which can print errors of its own. mbs
/// always names its devices, so the default is the CPU unless the user set
/// `BURN_DEVICE`.
fn default_to_the_cpu() {
    if std::env::var_os("BURN_DEVICE").is_none() {
        // SAFETY: the first statement of `main`, before any other thread
        // exists, so nothing reads the environment while it changes.
        #[allow(unsafe_code)]
        unsafe {
            std::env::set_var("BURN_DEVICE", "flex")
        };
    }
}

fn main() -> std::process::ExitCode {
    default_to_the_cpu();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(args) => commands::demo::run(args),
        Command::Synth(args) => commands::synth::run(args),
        Command::DecodeDepth(args) => commands::decode_depth::run(args),
        Command::Eval(args) => commands::eval::run(args),
        Command::Benchmark(args) => commands::benchmark::run(args),
        Command::Submit(args) => commands::submit::run(args),
        Command::Predict(args) => commands::predict::run(args),
        Command::Extrapolate(args) => commands::extrapolate::run(args),
        Command::Mono(args) => commands::mono::run(args),
        Command::Scan(args) => commands::scan::run(args),
        Command::Validate(args) => commands::validate::run(args),
        Command::Train(args) => commands::train::run(args),
        Command::Export(args) => commands::export::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // Rank 0 of the MPI job printed it.
        Err(e) if e.is::<mbs_train::launch::ReportedByRankZero>() => {
            std::process::ExitCode::FAILURE
        }
        Err(e) => {
            eprintln!("error: {}", cli::report_error::describe(&e));
            std::process::ExitCode::from(cli::exit_status(&e))
        }
    }
}
