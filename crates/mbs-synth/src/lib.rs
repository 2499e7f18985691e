//! Procedural street-like scenes rendered from a multi-baseline rig by exact
//! ray casting, with exact depth, disparity and occlusion ground truth: the
//! built-in data for demos and tests.
//!
//! Geometry follows conventions §2: camera `k` at `x = k * B`, all looking along
//! `+z`, `y` down, pinhole `f`, `cx`, `cy` from [`mbs_core::Rig`]. Textures are
//! defined on the 3D surface point (every view sees the same surface) and
//! band-limited to the pixel grid, so backward warping with the exact
//! disparity rebuilds a view closely. Generation and rendering are
//! deterministic: a seed gives the same images on every machine.
//!
//! ```
//! use mbs_core::Rig;
//! use mbs_synth::{RenderOptions, Scene, SceneConfig, occlusion_mask, one_step_disparity, render};
//!
//! let rig = Rig::centred(3, 0.5, 60.0, 48, 32);
//! let scene = Scene::generate(7, &SceneConfig::centred_on(&rig));
//! let out = render(&scene, &rig, &RenderOptions::default());
//! let disparity = one_step_disparity(&out.depth[0], &rig); // f * B / z
//! let occluded = occlusion_mask(&scene, &rig, 0, 2);
//! assert_eq!(out.views.len(), 3);
//! assert_eq!(disparity.dimensions(), occluded.dimensions());
//! ```

mod bvh;
pub mod dataset;
mod generate;
mod noise;
mod occlusion;
mod primitives;
mod render;
mod scene;
mod texture;
mod vec3;
mod weather;

pub use generate::SceneConfig;
pub use occlusion::occlusion_mask;
pub use primitives::Shape;
pub use render::{Render, RenderOptions, one_step_disparity, render};
pub use scene::{Object, Scene};
pub use texture::{Ground, Material, Pattern};
pub use weather::{ParseWeatherError, Weather};
