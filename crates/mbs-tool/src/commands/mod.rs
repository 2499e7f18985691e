//! One module per subcommand: argument parsing (clap) and orchestration only.

pub mod benchmark;
pub mod decode_depth;
pub mod demo;
pub mod eval;
pub mod export;
pub mod extrapolate;
pub mod mono;
pub mod predict;
pub mod scan;
pub mod submit;
pub mod synth;
pub mod train;
pub mod validate;
