//! Surface appearance: materials and their band-limited procedural textures,
//! defined on the 3D surface point so that every camera sees the same
//! surface. Detail finer than a few pixels is faded out (see `noise::Band`).

use serde::{Deserialize, Serialize};

use crate::noise::{Band, fbm, hash_unit, pulse, smoothstep};
use crate::vec3::Vec3;

/// A pattern drawn over a material's noise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Pattern {
    /// Noise only.
    Plain,
    /// A building facade: a grid of windows on vertical faces.
    Facade {
        /// Window cell size (horizontal, vertical) in metres.
        cell_m: [f64; 2],
        /// Fraction of the cell taken by the window (horizontal, vertical).
        window: [f64; 2],
    },
    /// Horizontal bands alternating base and accent colour.
    Bands {
        /// Period of the bands in metres.
        period_m: f64,
    },
}

/// How a surface looks: colours in display space (0..1) and texture scales.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// The pattern drawn on the surface.
    pub pattern: Pattern,
    /// Main colour.
    pub base: [f32; 3],
    /// Second colour, mixed in by large-scale noise and by the pattern.
    pub accent: [f32; 3],
    /// Period of the coarsest noise octave, in metres; finer octaves halve it.
    pub detail_period_m: f64,
    /// Seed of the noise.
    pub seed: u32,
}

/// The ground: a horizontal plane with a road (asphalt, lane markings)
/// between two sidewalks (tiles).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ground {
    /// Height of the plane: `y` coordinate (y points down, cameras at y = 0).
    pub y: f64,
    /// x of the road's centre line.
    pub road_centre_x: f64,
    /// Half the width of the road (kerb to kerb), in metres.
    pub road_half_width_m: f64,
    /// Seed of the noise.
    pub seed: u32,
}

/// Albedo and emission of a surface point.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Appearance {
    pub(crate) albedo: [f32; 3],
    pub(crate) emission: [f32; 3],
}

fn mix(a: [f32; 3], b: [f32; 3], t: f64) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0) as f32;
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

fn scale(a: [f32; 3], s: f64) -> [f32; 3] {
    let s = s.max(0.0) as f32;
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Edge softness (metres) for patterns under `band`: half the smallest period.
fn blur(band: Band) -> f64 {
    (0.5 * band.min_period_px * band.footprint_m).max(1e-6)
}

/// Base and accent mixed by large-scale noise, modulated by multi-scale noise.
fn noisy(m: &Material, p: Vec3, band: Band, contrast: f64) -> [f32; 3] {
    let tint = fbm(
        p,
        m.seed ^ 0x5bd1_e995,
        4.0 * m.detail_period_m,
        0.5,
        2,
        band,
    );
    let detail = fbm(p, m.seed, m.detail_period_m, 0.9, 7, band);
    scale(mix(m.base, m.accent, 0.5 + tint), 1.0 + contrast * detail)
}

impl Material {
    /// The appearance at surface point `p` with unit normal `n`;
    /// `window_glow` is the emission of lit windows (night).
    pub(crate) fn appearance(&self, p: Vec3, n: Vec3, band: Band, window_glow: f32) -> Appearance {
        let mut emission = [0.0; 3];
        let albedo = match self.pattern {
            Pattern::Plain => noisy(self, p, band, 0.55),
            Pattern::Bands { period_m } => {
                let stripe = pulse(p.y, period_m, 0.5, blur(band));
                mix(noisy(self, p, band, 0.45), self.accent, 0.8 * stripe)
            }
            Pattern::Facade { cell_m, window } => {
                let wall = || noisy(self, p, band, 0.5);
                let h = if n.x.abs() > 0.5 { p.z } else { p.x };
                let b = blur(band);
                let win = if n.y.abs() > 0.5 {
                    0.0
                } else {
                    pulse(h, cell_m[0], window[0], b) * pulse(p.y, cell_m[1], window[1], b)
                };
                if win <= 0.0 {
                    wall()
                } else {
                    let glass_shade = 0.5 + 0.25 * fbm(p, self.seed ^ 0x9e37, 2.0, 0.6, 4, band);
                    let glass = scale([0.16, 0.20, 0.26], glass_shade * 2.0);
                    if window_glow > 0.0 {
                        let cell = |v: f64, s: f64| (v / s).floor() as i64;
                        let lit = hash_unit(cell(h, cell_m[0]), cell(p.y, cell_m[1]), 0, self.seed);
                        if lit < 0.45 {
                            let g = window_glow * (0.6 + 0.8 * lit as f32) * win as f32;
                            emission = [g, 0.8 * g, 0.5 * g];
                        }
                    }
                    if win >= 1.0 {
                        glass
                    } else {
                        mix(wall(), glass, win)
                    }
                }
            }
        };
        Appearance { albedo, emission }
    }
}

impl Ground {
    /// The albedo at ground point `p`; `wetness` in [0, 1] darkens it.
    pub(crate) fn albedo(&self, p: Vec3, band: Band, wetness: f32) -> [f32; 3] {
        let b = blur(band);
        let dx = (p.x - self.road_centre_x).abs();
        let asphalt = Material {
            pattern: Pattern::Plain,
            base: [0.26, 0.26, 0.27],
            accent: [0.34, 0.32, 0.30],
            detail_period_m: 3.0,
            seed: self.seed,
        };
        let on_walk = smoothstep(self.road_half_width_m - b, self.road_half_width_m + b, dx);
        let road = || {
            // Dashed centre line and solid edge lines, 15 cm wide.
            let centre = smoothstep(0.075 + b, 0.075 - b, dx) * pulse(p.z, 6.0, 0.5, b);
            let edge_dist = (dx - (self.road_half_width_m - 0.35)).abs();
            let edge = smoothstep(0.075 + b, 0.075 - b, edge_dist);
            mix(
                noisy(&asphalt, p, band, 0.5),
                [0.85, 0.85, 0.80],
                centre.max(edge) * 0.9,
            )
        };
        let tiles = Material {
            pattern: Pattern::Plain,
            base: [0.55, 0.52, 0.48],
            accent: [0.62, 0.60, 0.58],
            detail_period_m: 1.5,
            seed: self.seed ^ 0x2545_f491,
        };
        let walk = || {
            let grout = 1.0 - pulse(p.x, 0.6, 0.9, b) * pulse(p.z, 0.6, 0.9, b);
            scale(noisy(&tiles, p, band, 0.45), 1.0 - 0.45 * grout)
        };
        // Only the kerb's soft edge needs both surfaces.
        let albedo = if on_walk <= 0.0 {
            road()
        } else if on_walk >= 1.0 {
            walk()
        } else {
            mix(road(), walk(), on_walk)
        };
        scale(albedo, 1.0 - 0.5 * f64::from(wetness))
    }
}
