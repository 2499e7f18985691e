//! Procedural street scenes from a seed: facades on both sides of a street
//! and at its end, car-sized boxes on the road, poles on the sidewalks.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::primitives::Shape;
use crate::scene::{Object, Scene};
use crate::texture::{Ground, Material, Pattern};

/// Parameters of a generated street scene (metres). Every field has a
/// default, so a partial JSON object deserialises.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneConfig {
    /// x of the street's centre line; put it at the rig's centre,
    /// `(N - 1) * B / 2` (the default, 1.0, suits MBS20K's rig).
    pub centre_x_m: f64,
    /// Height of the cameras above the ground.
    pub camera_height_m: f64,
    /// Distance between the facades on both sides.
    pub street_width_m: f64,
    /// Width of each sidewalk (between road and facade).
    pub sidewalk_width_m: f64,
    /// Nearest depth at which boxes and poles are placed.
    pub min_depth_m: f64,
    /// Length of the street; buildings close it beyond this depth.
    pub max_depth_m: f64,
    /// Number of boxes (cars, crates) on the road.
    pub boxes: usize,
    /// Number of poles on the sidewalks.
    pub poles: usize,
    /// Whether facades line both sides of the street.
    pub side_buildings: bool,
    /// Whether buildings close the street at its far end.
    pub back_buildings: bool,
}

impl Default for SceneConfig {
    fn default() -> SceneConfig {
        SceneConfig {
            centre_x_m: 1.0,
            camera_height_m: 1.7,
            street_width_m: 16.0,
            sidewalk_width_m: 3.0,
            min_depth_m: 4.0,
            max_depth_m: 90.0,
            boxes: 8,
            poles: 8,
            side_buildings: true,
            back_buildings: true,
        }
    }
}

impl SceneConfig {
    /// The default configuration with the street centred on `rig`.
    pub fn centred_on(rig: &mbs_core::Rig) -> SceneConfig {
        SceneConfig {
            centre_x_m: rig.camera_x(rig.num_views.saturating_sub(1)) / 2.0,
            ..SceneConfig::default()
        }
    }
}

/// Uniform in `[a, b)`; `a` when the range is empty (never panics).
fn uniform(rng: &mut ChaCha8Rng, a: f64, b: f64) -> f64 {
    if b > a {
        a + (b - a) * rng.random::<f64>()
    } else {
        a
    }
}

fn pick(rng: &mut ChaCha8Rng, colours: &[[f32; 3]]) -> [f32; 3] {
    let base = colours[rng.random_range(0..colours.len())];
    let jitter = uniform(rng, 0.85, 1.15) as f32;
    base.map(|c| (c * jitter).min(1.0))
}

fn shade(c: [f32; 3], s: f32) -> [f32; 3] {
    c.map(|v| (v * s).min(1.0))
}

const WALLS: [[f32; 3]; 7] = [
    [0.62, 0.36, 0.28],
    [0.78, 0.72, 0.60],
    [0.55, 0.55, 0.55],
    [0.85, 0.83, 0.78],
    [0.45, 0.50, 0.58],
    [0.70, 0.55, 0.40],
    [0.50, 0.42, 0.36],
];

const PAINTS: [[f32; 3]; 8] = [
    [0.75, 0.10, 0.10],
    [0.10, 0.25, 0.65],
    [0.85, 0.85, 0.85],
    [0.12, 0.12, 0.13],
    [0.55, 0.58, 0.60],
    [0.80, 0.65, 0.10],
    [0.20, 0.45, 0.25],
    [0.55, 0.38, 0.22],
];

fn facade(rng: &mut ChaCha8Rng) -> Material {
    let base = pick(rng, &WALLS);
    Material {
        pattern: Pattern::Facade {
            cell_m: [uniform(rng, 2.4, 4.0), uniform(rng, 3.0, 3.6)],
            window: [uniform(rng, 0.35, 0.65), uniform(rng, 0.4, 0.6)],
        },
        base,
        accent: shade(pick(rng, &WALLS), 0.8),
        detail_period_m: uniform(rng, 1.5, 4.0),
        seed: rng.random(),
    }
}

fn cuboid(min: [f64; 3], max: [f64; 3], material: Material) -> Object {
    Object {
        shape: Shape::Cuboid { min, max },
        material,
    }
}

/// The street's layout in the scene's frame, derived from a [`SceneConfig`].
struct Street<'a> {
    /// The configuration it was derived from.
    config: &'a SceneConfig,
    /// x of the street's centre line.
    centre_x: f64,
    /// y of the ground (the cameras look down +y).
    ground_y: f64,
    /// Half the distance between the facades.
    half_width: f64,
    /// Half the road's width (at least 0.5 m).
    road_half: f64,
}

impl Street<'_> {
    /// Facades along both sides of the street, block after block up to
    /// `max_depth_m`, some with gaps between them.
    fn side_buildings(&self, rng: &mut ChaCha8Rng, objects: &mut Vec<Object>) {
        let (c, gy, half) = (self.centre_x, self.ground_y, self.half_width);
        for side in [-1.0, 1.0] {
            let mut z = -10.0;
            while z < self.config.max_depth_m {
                let len = uniform(rng, 8.0, 22.0);
                let gap = if rng.random::<f64>() < 0.3 {
                    uniform(rng, 2.0, 5.0)
                } else {
                    0.0
                };
                let face = c + side * (half + uniform(rng, 0.0, 1.5));
                let back = face + side * 12.0;
                let height = uniform(rng, 6.0, 28.0);
                let material = facade(rng);
                objects.push(cuboid(
                    [face.min(back), gy - height, z],
                    [face.max(back), gy, z + len],
                    material,
                ));
                z += len + gap;
            }
        }
    }

    /// A row of buildings beyond `max_depth_m` closing the street, with
    /// occasional gaps.
    fn back_buildings(&self, rng: &mut ChaCha8Rng, objects: &mut Vec<Object>) {
        let (c, gy) = (self.centre_x, self.ground_y);
        let z_back = self.config.max_depth_m + uniform(rng, 5.0, 25.0);
        let mut x = c - 90.0;
        while x < c + 90.0 {
            let width = uniform(rng, 10.0, 30.0);
            if rng.random::<f64>() < 0.85 {
                let z0 = z_back + uniform(rng, 0.0, 15.0);
                let height = uniform(rng, 10.0, 50.0);
                let material = facade(rng);
                objects.push(cuboid(
                    [x, gy - height, z0],
                    [x + width, gy, z0 + 15.0],
                    material,
                ));
            }
            x += width;
        }
    }

    /// `config.boxes` car- or crate-sized boxes on the road, each tried up
    /// to 20 times at random places until it keeps 0.5 m from the others
    /// (a box that never fits is left out).
    fn boxes(&self, rng: &mut ChaCha8Rng, objects: &mut Vec<Object>) {
        let mut placed: Vec<([f64; 3], [f64; 3])> = Vec::new();
        for _ in 0..self.config.boxes {
            for _attempt in 0..20 {
                let crate_like = rng.random::<f64>() < 0.3;
                let (min, max) = self.random_box(rng, crate_like);
                let clear = placed.iter().all(|(a, b)| {
                    max[0] + 0.5 < a[0]
                        || b[0] + 0.5 < min[0]
                        || max[2] + 0.5 < a[2]
                        || b[2] + 0.5 < min[2]
                });
                if clear {
                    placed.push((min, max));
                    objects.push(cuboid(min, max, box_paint(rng, crate_like)));
                    break;
                }
            }
        }
    }

    /// The corners of a box at a random place on the road: a crate (a
    /// rough cube) or a car.
    fn random_box(&self, rng: &mut ChaCha8Rng, crate_like: bool) -> ([f64; 3], [f64; 3]) {
        let (w, h, l) = if crate_like {
            let s = uniform(rng, 0.6, 1.5);
            (s, s * uniform(rng, 0.8, 1.2), s)
        } else {
            (
                uniform(rng, 1.6, 2.2),
                uniform(rng, 1.2, 2.4),
                uniform(rng, 3.5, 5.0),
            )
        };
        let gy = self.ground_y;
        let x0 = self.centre_x + uniform(rng, -self.road_half, self.road_half - w);
        let z0 = uniform(rng, self.config.min_depth_m, 0.7 * self.config.max_depth_m);
        ([x0, gy - h, z0], [x0 + w, gy, z0 + l])
    }

    /// `config.poles` banded poles on the sidewalks, on either side.
    fn poles(&self, rng: &mut ChaCha8Rng, objects: &mut Vec<Object>) {
        let config = self.config;
        for _ in 0..config.poles {
            let side = if rng.random::<bool>() { 1.0 } else { -1.0 };
            let offset = uniform(rng, 0.4, (config.sidewalk_width_m - 0.4).max(0.4));
            let material = Material {
                pattern: Pattern::Bands {
                    period_m: uniform(rng, 0.4, 1.5),
                },
                base: pick(rng, &[[0.45, 0.47, 0.50], [0.20, 0.30, 0.22]]),
                accent: pick(rng, &[[0.85, 0.75, 0.15], [0.85, 0.85, 0.85]]),
                detail_period_m: uniform(rng, 0.5, 1.5),
                seed: rng.random(),
            };
            let height = uniform(rng, 2.5, 8.0);
            objects.push(Object {
                shape: Shape::Cylinder {
                    centre_x: self.centre_x + side * (self.road_half + offset),
                    centre_z: uniform(rng, config.min_depth_m, 0.8 * config.max_depth_m),
                    radius: uniform(rng, 0.08, 0.25),
                    top_y: self.ground_y - height,
                    bottom_y: self.ground_y,
                },
                material,
            });
        }
    }
}

/// A box's paint: banded for a crate, plain for a car.
fn box_paint(rng: &mut ChaCha8Rng, crate_like: bool) -> Material {
    Material {
        pattern: if crate_like {
            Pattern::Bands {
                period_m: uniform(rng, 0.2, 0.5),
            }
        } else {
            Pattern::Plain
        },
        base: pick(rng, &PAINTS),
        accent: pick(rng, &PAINTS),
        detail_period_m: uniform(rng, 0.5, 2.0),
        seed: rng.random(),
    }
}

impl Scene {
    /// A street scene generated from `seed` (ChaCha8: the same on every
    /// machine). Nothing is placed nearer than `min_depth_m` on the road.
    pub fn generate(seed: u64, config: &SceneConfig) -> Scene {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let half_width = config.street_width_m / 2.0;
        let street = Street {
            config,
            centre_x: config.centre_x_m,
            ground_y: config.camera_height_m,
            half_width,
            road_half: (half_width - config.sidewalk_width_m).max(0.5),
        };
        // The parts draw from one generator in this order, so a seed gives
        // the same scene as it always has.
        let mut objects = Vec::new();
        if config.side_buildings {
            street.side_buildings(&mut rng, &mut objects);
        }
        if config.back_buildings {
            street.back_buildings(&mut rng, &mut objects);
        }
        street.boxes(&mut rng, &mut objects);
        street.poles(&mut rng, &mut objects);
        let ground = Ground {
            y: street.ground_y,
            road_centre_x: street.centre_x,
            road_half_width_m: street.road_half,
            seed: rng.random(),
        };
        Scene::new(Some(ground), objects, rng.random())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_round_trips_and_fills_defaults() {
        let config = SceneConfig {
            boxes: 3,
            ..SceneConfig::default()
        };
        let json = serde_json::to_string(&config).unwrap();
        assert_eq!(serde_json::from_str::<SceneConfig>(&json).unwrap(), config);
        let partial: SceneConfig = serde_json::from_str(r#"{"poles": 2}"#).unwrap();
        assert_eq!(partial.poles, 2);
        assert_eq!(
            partial.street_width_m,
            SceneConfig::default().street_width_m
        );
        assert!(serde_json::from_str::<SceneConfig>(r#"{"polls": 2}"#).is_err());
    }

    #[test]
    fn degenerate_configs_do_not_panic() {
        let config = SceneConfig {
            street_width_m: -3.0,
            sidewalk_width_m: 50.0,
            min_depth_m: 80.0,
            max_depth_m: 1.0,
            ..SceneConfig::default()
        };
        let scene = Scene::generate(1, &config);
        assert!(scene.ground().is_some());
    }

    #[test]
    fn default_street_has_every_kind_of_object() {
        let config = SceneConfig::default();
        let scene = Scene::generate(2, &config);
        let count = |f: fn(&Object) -> bool| scene.objects().iter().filter(|o| f(o)).count();
        assert_eq!(
            count(|o| matches!(o.shape, Shape::Cylinder { .. })),
            config.poles
        );
        assert!(count(|o| matches!(o.material.pattern, Pattern::Facade { .. })) > 10);
        // Nothing on the road nearer than min_depth_m.
        for o in scene.objects() {
            if let Shape::Cuboid { min, max } = o.shape {
                let on_road = max[0] > config.centre_x_m - 5.0 && min[0] < config.centre_x_m + 5.0;
                assert!(!on_road || min[2] >= config.min_depth_m || max[2] <= 0.0);
            }
        }
    }
}
