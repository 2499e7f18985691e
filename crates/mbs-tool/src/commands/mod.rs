//! One module per subcommand: argument parsing (clap) and orchestration only.

pub mod decode_depth;
pub mod extrapolate;
pub mod scan;
pub mod validate;
