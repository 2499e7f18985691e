//! A scene: the ground, a set of textured objects, and the sky on the far
//! plane; closest-hit and visibility queries against it.

use mbs_core::formats::carla::FAR_PLANE_M;

use crate::bvh::Bvh;
use crate::primitives::{Ray, Shape};
use crate::texture::{Ground, Material};
use crate::vec3::Vec3;

/// One object of a scene: a shape and its material.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Object {
    /// The geometry.
    pub shape: Shape,
    /// The appearance.
    pub material: Material,
}

/// A static scene. The sky is the far plane `z = 1000 m` (CARLA's far
/// plane): every camera ray that meets nothing nearer ends there.
#[derive(Debug, Clone)]
pub struct Scene {
    ground: Option<Ground>,
    objects: Vec<Object>,
    shapes: Vec<Shape>,
    bvh: Bvh,
    sky_seed: u32,
}

/// What a ray hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Surface {
    Object(usize),
    Ground,
    Sky,
}

/// The nearest hit of a ray.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Hit {
    pub(crate) t: f64,
    pub(crate) normal: Vec3,
    pub(crate) surface: Surface,
}

impl Scene {
    /// A scene from hand-placed parts: an optional ground plane, objects,
    /// and the seed of the sky's cloud texture.
    pub fn new(ground: Option<Ground>, objects: Vec<Object>, sky_seed: u32) -> Scene {
        let shapes: Vec<Shape> = objects.iter().map(|o| o.shape).collect();
        let bvh = Bvh::build(&shapes);
        Scene {
            ground,
            objects,
            shapes,
            bvh,
            sky_seed,
        }
    }

    /// The ground plane, if any.
    pub fn ground(&self) -> Option<&Ground> {
        self.ground.as_ref()
    }

    /// The objects.
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    pub(crate) fn sky_seed(&self) -> u32 {
        self.sky_seed
    }

    /// The ray parameter where the ground plane is met, if in `(t_min, t_max)`.
    fn ground_t(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<f64> {
        let g = self.ground?;
        if ray.dir.y == 0.0 {
            return None;
        }
        let t = (g.y - ray.origin.y) / ray.dir.y;
        (t > t_min && t < t_max).then_some(t)
    }

    /// The nearest surface along the ray beyond `t_min`, the sky plane
    /// included (None only for rays that never reach `z = 1000 m`).
    pub(crate) fn trace(&self, ray: &Ray, t_min: f64) -> Option<Hit> {
        let sky_t = if ray.dir.z > 0.0 {
            (FAR_PLANE_M - ray.origin.z) / ray.dir.z
        } else {
            f64::INFINITY
        };
        let mut best = if sky_t.is_finite() {
            Some(Hit {
                t: sky_t,
                normal: Vec3::new(0.0, 0.0, -1.0),
                surface: Surface::Sky,
            })
        } else {
            None
        };
        if let Some(t) = self.ground_t(ray, t_min, sky_t) {
            let up = if ray.dir.y > 0.0 { -1.0 } else { 1.0 };
            best = Some(Hit {
                t,
                normal: Vec3::new(0.0, up, 0.0),
                surface: Surface::Ground,
            });
        }
        let limit = best.map_or(f64::INFINITY, |h| h.t);
        if let Some((hit, i)) = self.bvh.closest(&self.shapes, ray, t_min, limit) {
            best = Some(Hit {
                t: hit.t,
                normal: hit.normal,
                surface: Surface::Object(i),
            });
        }
        best
    }

    /// Whether the ground or an object lies on the ray within `(t_min, t_max)`.
    pub(crate) fn blocked(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        self.ground_t(ray, t_min, t_max).is_some() || self.bvh.any(&self.shapes, ray, t_min, t_max)
    }
}
