//! The rig flags shared by commands that describe or create MBS20K-style
//! data (defaults: MBS20K's 5 cameras, B = 0.5 m, f = 480 px, 960x540).

use clap::Args;
use mbs_core::Rig;

/// `--views --width --height --focal --baseline`.
#[derive(Debug, Clone, Args)]
pub struct RigArgs {
    /// Number of cameras.
    #[arg(long, default_value_t = 5)]
    pub views: usize,
    /// Image width in pixels.
    #[arg(long, default_value_t = 960)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 540)]
    pub height: u32,
    /// Focal length in pixels.
    #[arg(long, default_value_t = 480.0)]
    pub focal: f64,
    /// Baseline between neighbouring cameras in metres.
    #[arg(long, default_value_t = 0.5)]
    pub baseline: f64,
}

impl RigArgs {
    /// The rig, principal point at the image centre; refuses degenerate values.
    pub fn rig(&self) -> anyhow::Result<Rig> {
        if self.views < 2 || self.width == 0 || self.height == 0 {
            anyhow::bail!("need at least 2 views and a non-empty image size");
        }
        if !(self.focal > 0.0 && self.baseline > 0.0) {
            anyhow::bail!("--focal and --baseline must be positive");
        }
        Ok(Rig::centred(
            self.views,
            self.baseline,
            self.focal,
            self.width,
            self.height,
        ))
    }
}
