//! The rig flags shared by commands that describe or create MBS20K-style
//! data (defaults: MBS20K's 5 cameras, B = 0.5 m, f = 480 px, 960x540).

use clap::Args;
use mbs_core::Rig;

/// `--views --width --height --focal --baseline`.
#[derive(Debug, Clone, Args)]
pub struct RigArgs {
    /// Number of cameras.
    #[arg(long, default_value_t = 5, value_parser = crate::cli::values::views)]
    pub views: usize,
    /// Image width in pixels.
    #[arg(long, default_value_t = 960, value_parser = crate::cli::values::image_side)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 540, value_parser = crate::cli::values::image_side)]
    pub height: u32,
    /// Focal length in pixels.
    #[arg(long, default_value_t = 480.0, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub focal: f64,
    /// Baseline between neighbouring cameras in metres.
    #[arg(long, default_value_t = 0.5, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub baseline: f64,
}

impl RigArgs {
    /// The rig, principal point at the image centre (the flags' parsers
    /// have checked every value's range).
    pub fn rig(&self) -> Rig {
        Rig::centred(
            self.views,
            self.baseline,
            self.focal,
            self.width,
            self.height,
        )
    }
}
