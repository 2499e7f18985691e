//! Exact occlusion ground truth between two cameras of a rig.

use mbs_core::{MaskImage, Rig};
use rayon::prelude::*;

use crate::primitives::Ray;
use crate::render::camera_ray;
use crate::scene::Scene;

/// Relative tolerance along the segment from the target camera to the point:
/// a surface counts as blocking only if it is nearer than `1 - EPS` of the way.
const EPS: f64 = 1e-6;

/// The occlusion mask of camera `reference` with respect to camera `target`:
/// 255 where the surface point seen through the pixel centre of `reference`
/// is not visible from `target` (another surface lies between them, or it
/// projects outside `[0, width - 1]` columns of the target, as
/// `mbs_image::resample::warp_from_target` would reject it), 0 elsewhere.
/// Computed by casting a ray from the target camera to each point.
///
/// # Panics
/// When `reference` or `target` is not a camera of `rig`.
pub fn occlusion_mask(scene: &Scene, rig: &Rig, reference: usize, target: usize) -> MaskImage {
    assert!(
        reference < rig.num_views && target < rig.num_views,
        "camera index out of range: {reference}, {target} for {} views",
        rig.num_views
    );
    let (width, height) = (rig.width, rig.height);
    let w = width as usize;
    let mut mask = MaskImage::new(width, height);
    if w == 0 || reference == target {
        return mask;
    }
    let target_x = rig.camera_x(target);
    let max_u = f64::from(width) - 1.0;
    mask.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
        for (x, m) in out.iter_mut().enumerate() {
            let ray = camera_ray(rig, reference, x as f64, row as f64);
            let Some(hit) = scene.trace(&ray, 0.0) else {
                *m = 255;
                continue;
            };
            let p = ray.origin + ray.dir * hit.t;
            let u = rig.focal_px * (p.x - target_x) / p.z + rig.cx;
            let outside = !(0.0..=max_u).contains(&u);
            let origin = camera_ray(rig, target, 0.0, 0.0).origin;
            let back = Ray {
                origin,
                dir: p - origin,
            };
            if outside || scene.blocked(&back, EPS, 1.0 - EPS) {
                *m = 255;
            }
        }
    });
    mask
}
