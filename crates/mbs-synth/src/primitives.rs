//! Scene primitives (axis-aligned cuboids, vertical cylinders) and their
//! exact ray intersection in f64.

use serde::{Deserialize, Serialize};

use crate::vec3::Vec3;

/// The shape of one scene object, in world coordinates (metres; x right,
/// y down, z forward, conventions §2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    /// An axis-aligned box between two corners (`min` < `max` on every axis).
    Cuboid {
        /// The corner with the smallest x, y and z.
        min: [f64; 3],
        /// The corner with the largest x, y and z.
        max: [f64; 3],
    },
    /// A capped cylinder whose axis is vertical (parallel to y).
    Cylinder {
        /// x of the axis.
        centre_x: f64,
        /// z of the axis.
        centre_z: f64,
        /// Radius in metres.
        radius: f64,
        /// y of the top cap (the smaller y: y points down).
        top_y: f64,
        /// y of the bottom cap.
        bottom_y: f64,
    },
}

/// A ray `origin + t * dir`, `t > 0`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ray {
    pub(crate) origin: Vec3,
    pub(crate) dir: Vec3,
}

/// The nearest intersection of a ray with one primitive.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PrimHit {
    /// Ray parameter of the hit.
    pub(crate) t: f64,
    /// Unit surface normal, facing the ray origin.
    pub(crate) normal: Vec3,
}

/// An axis-aligned bounding box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Aabb {
    pub(crate) min: Vec3,
    pub(crate) max: Vec3,
}

impl Aabb {
    pub(crate) fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: Vec3::new(
                self.min.x.min(o.min.x),
                self.min.y.min(o.min.y),
                self.min.z.min(o.min.z),
            ),
            max: Vec3::new(
                self.max.x.max(o.max.x),
                self.max.y.max(o.max.y),
                self.max.z.max(o.max.z),
            ),
        }
    }

    pub(crate) fn centre(self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// The entry/exit parameters of the ray through the box, clipped to
    /// `(t_min, t_max)`, with the axis through which it enters; `None` when
    /// it misses. A zero direction component is handled exactly.
    fn slabs(self, ray: &Ray, t_min: f64, t_max: f64) -> Option<(f64, f64, usize)> {
        let mut t0 = f64::NEG_INFINITY;
        let mut t1 = f64::INFINITY;
        let mut axis = 0;
        for i in 0..3 {
            let o = ray.origin.axis(i);
            let d = ray.dir.axis(i);
            let (lo, hi) = (self.min.axis(i), self.max.axis(i));
            if d == 0.0 {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let (a, b) = ((lo - o) / d, (hi - o) / d);
            let (near, far) = if a < b { (a, b) } else { (b, a) };
            if near > t0 {
                t0 = near;
                axis = i;
            }
            t1 = t1.min(far);
        }
        (t0 <= t1 && t1 > t_min && t0 < t_max).then_some((t0, t1, axis))
    }

    /// Whether the ray meets the box within `(t_min, t_max)`.
    pub(crate) fn hit_by(self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        self.slabs(ray, t_min, t_max).is_some()
    }
}

impl Shape {
    /// The bounding box of the shape.
    pub(crate) fn bounds(&self) -> Aabb {
        match *self {
            Shape::Cuboid { min, max } => Aabb {
                min: Vec3::from_array(min),
                max: Vec3::from_array(max),
            },
            Shape::Cylinder {
                centre_x,
                centre_z,
                radius,
                top_y,
                bottom_y,
            } => Aabb {
                min: Vec3::new(centre_x - radius, top_y, centre_z - radius),
                max: Vec3::new(centre_x + radius, bottom_y, centre_z + radius),
            },
        }
    }

    /// The nearest intersection with `t` in `(t_min, t_max)`.
    pub(crate) fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<PrimHit> {
        match *self {
            Shape::Cuboid { .. } => intersect_cuboid(self.bounds(), ray, t_min, t_max),
            Shape::Cylinder {
                centre_x,
                centre_z,
                radius,
                top_y,
                bottom_y,
            } => intersect_cylinder(
                (centre_x, centre_z, radius, top_y, bottom_y),
                ray,
                t_min,
                t_max,
            ),
        }
    }
}

fn unit_axis(axis: usize, sign: f64) -> Vec3 {
    match axis {
        0 => Vec3::new(sign, 0.0, 0.0),
        1 => Vec3::new(0.0, sign, 0.0),
        _ => Vec3::new(0.0, 0.0, sign),
    }
}

fn intersect_cuboid(b: Aabb, ray: &Ray, t_min: f64, t_max: f64) -> Option<PrimHit> {
    let (t0, t1, axis) = b.slabs(ray, t_min, t_max)?;
    if t0 > t_min {
        // Entering face: the normal opposes the ray along the entry axis.
        let sign = if ray.dir.axis(axis) > 0.0 { -1.0 } else { 1.0 };
        return Some(PrimHit {
            t: t0,
            normal: unit_axis(axis, sign),
        });
    }
    // The origin is inside the box: report the exit face, seen from inside.
    if t1 >= t_max {
        return None;
    }
    let p = ray.origin + ray.dir * t1;
    let mut best = (f64::INFINITY, 0, 1.0);
    for i in 0..3 {
        for (plane, sign) in [(b.min.axis(i), 1.0), (b.max.axis(i), -1.0)] {
            let dist = (p.axis(i) - plane).abs();
            if dist < best.0 {
                best = (dist, i, sign);
            }
        }
    }
    Some(PrimHit {
        t: t1,
        normal: unit_axis(best.1, best.2),
    })
}

fn intersect_cylinder(
    (cx, cz, r, top_y, bottom_y): (f64, f64, f64, f64, f64),
    ray: &Ray,
    t_min: f64,
    t_max: f64,
) -> Option<PrimHit> {
    let mut best: Option<PrimHit> = None;
    let mut consider = |t: f64, normal: Vec3| {
        if t > t_min && t < t_max && best.is_none_or(|b| t < b.t) {
            best = Some(PrimHit { t, normal });
        }
    };
    let (ox, oz) = (ray.origin.x - cx, ray.origin.z - cz);
    let (dx, dz) = (ray.dir.x, ray.dir.z);
    let a = dx * dx + dz * dz;
    if a > 0.0 {
        let b = ox * dx + oz * dz;
        let c = ox * ox + oz * oz - r * r;
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let root = disc.sqrt();
            for t in [(-b - root) / a, (-b + root) / a] {
                let y = ray.origin.y + t * ray.dir.y;
                if y >= top_y && y <= bottom_y {
                    let n = Vec3::new(ox + t * dx, 0.0, oz + t * dz) * (1.0 / r);
                    let facing = if n.dot(ray.dir) > 0.0 { n * -1.0 } else { n };
                    consider(t, facing);
                }
            }
        }
    }
    if ray.dir.y != 0.0 {
        for (cap_y, sign) in [(top_y, -1.0), (bottom_y, 1.0)] {
            let t = (cap_y - ray.origin.y) / ray.dir.y;
            let (px, pz) = (ox + t * dx, oz + t * dz);
            if px * px + pz * pz <= r * r {
                let n = Vec3::new(0.0, sign, 0.0);
                let facing = if n.dot(ray.dir) > 0.0 { n * -1.0 } else { n };
                consider(t, facing);
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: [f64; 3], d: [f64; 3]) -> Ray {
        Ray {
            origin: Vec3::from_array(o),
            dir: Vec3::from_array(d),
        }
    }

    #[test]
    fn cuboid_front_face_and_miss() {
        let s = Shape::Cuboid {
            min: [-1.0, -1.0, 5.0],
            max: [1.0, 1.0, 7.0],
        };
        let hit = s
            .intersect(&ray([0.0, 0.0, 0.0], [0.1, 0.0, 1.0]), 0.0, f64::INFINITY)
            .unwrap();
        assert_eq!(hit.t, 5.0);
        assert_eq!(hit.normal, Vec3::new(0.0, 0.0, -1.0));
        assert!(
            s.intersect(&ray([0.0, 0.0, 0.0], [0.5, 0.0, 1.0]), 0.0, f64::INFINITY)
                .is_none()
        );
        // Clipped by t_max.
        assert!(
            s.intersect(&ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]), 0.0, 4.0)
                .is_none()
        );
    }

    #[test]
    fn cylinder_side_and_cap() {
        let s = Shape::Cylinder {
            centre_x: 0.0,
            centre_z: 10.0,
            radius: 0.5,
            top_y: -2.0,
            bottom_y: 2.0,
        };
        let side = s
            .intersect(&ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]), 0.0, f64::INFINITY)
            .unwrap();
        assert!((side.t - 9.5).abs() < 1e-12);
        assert_eq!(side.normal, Vec3::new(0.0, 0.0, -1.0));
        // From above, looking down onto the top cap.
        let cap = s
            .intersect(&ray([0.0, -5.0, 10.0], [0.0, 1.0, 0.0]), 0.0, f64::INFINITY)
            .unwrap();
        assert_eq!(cap.t, 3.0);
        assert_eq!(cap.normal, Vec3::new(0.0, -1.0, 0.0));
    }
}
