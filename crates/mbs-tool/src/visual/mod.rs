//! What `mbs-tool train` draws for a person to look at: loss curves as PNG
//! plots, the occlusion-aware weight map of the paper (which pixels the
//! student learns from, and how strongly), and contact sheets that put a
//! step's images side by side.
//!
//! Plots are drawn with tiny-skia (anti-aliased lines) and a built-in
//! bitmap font; images are the `image` crate's RGB buffers, coloured with
//! `mbs_core::colormap` where they are disparities.

mod axis;
mod font;
mod plot;
mod weight_map;

pub(crate) use plot::{Series, write_loss_plot};
pub(crate) use weight_map::{side_by_side, weight_map_image};
