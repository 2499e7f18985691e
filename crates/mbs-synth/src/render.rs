//! Exact ray casting of a scene from every camera of a rig: supersampled
//! colour views and planar depth (sky = 1000 m), plus the exact one-step
//! disparity derived from the depth.

use mbs_core::geometry::depth_to_disparity;
use mbs_core::{FloatImage, RgbImage, Rig};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::noise::{Band, fbm, smoothstep};
use crate::primitives::Ray;
use crate::scene::{Hit, Scene, Surface};
use crate::vec3::Vec3;
use crate::weather::{Lighting, Weather};

/// How to render.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderOptions {
    /// Samples per pixel along each axis (`s x s` per pixel, box filter);
    /// 0 counts as 1.
    pub supersample: u32,
    /// Lighting preset.
    pub weather: Weather,
    /// Texture detail whose period would be below this many pixels (across
    /// the rig's horizontal direction) is faded out, so that views stay
    /// band-limited and warp well; clamped to at least 1.
    pub min_texture_period_px: f64,
}

impl Default for RenderOptions {
    fn default() -> RenderOptions {
        RenderOptions {
            supersample: 2,
            weather: Weather::ClearNoon,
            min_texture_period_px: 3.0,
        }
    }
}

/// The output of [`render`]: one view and one depth map per camera.
#[derive(Debug, Clone)]
pub struct Render {
    /// Colour views, camera 0..N-1.
    pub views: Vec<RgbImage>,
    /// Planar depth z (metres) of each pixel centre's ray, camera 0..N-1;
    /// the sky is exactly 1000 m.
    pub depth: Vec<FloatImage>,
}

/// The ray through pixel `(u, v)` (column, row; integer = pixel centre) of
/// camera `k`. The direction has `z = 1`, so the ray parameter is the planar
/// depth.
pub(crate) fn camera_ray(rig: &Rig, k: usize, u: f64, v: f64) -> Ray {
    Ray {
        origin: Vec3::new(rig.camera_x(k), 0.0, 0.0),
        dir: Vec3::new(
            (u - rig.cx) / rig.focal_px,
            (v - rig.cy) / rig.focal_px,
            1.0,
        ),
    }
}

/// Everything a pixel needs besides the scene, shared by all cameras so that
/// texture filtering is the same in every view.
struct Shader<'a> {
    scene: &'a Scene,
    light: Lighting,
    /// The rig's centre: the view point for texture filtering.
    centre: Vec3,
    focal_px: f64,
    min_period_px: f64,
}

impl Shader<'_> {
    /// World size of a pixel at `p` on a surface with normal `n`, seen from
    /// the rig's centre: the larger of the step along the surface for one
    /// pixel across, and a quarter of the step for one pixel down.
    fn band(&self, p: Vec3, n: Vec3) -> Band {
        let z = (p.z - self.centre.z).max(1e-6);
        let d = (p - self.centre) * (1.0 / z);
        let nd = n.dot(d);
        let nd = if nd.abs() < 1e-3 {
            1e-3f64.copysign(nd)
        } else {
            nd
        };
        let across = (Vec3::new(1.0, 0.0, 0.0) - d * (n.x / nd)).length();
        let down = (Vec3::new(0.0, 1.0, 0.0) - d * (n.y / nd)).length();
        Band {
            footprint_m: z / self.focal_px * across.max(0.25 * down),
            min_period_px: self.min_period_px,
        }
    }

    fn sky(&self, p: Vec3, band: Band) -> [f32; 3] {
        let l = &self.light;
        let elevation = (-p.y / 400.0).clamp(0.0, 1.0);
        let t = elevation.sqrt() as f32;
        let base: [f32; 3] =
            std::array::from_fn(|i| l.sky_horizon[i] + (l.sky_zenith[i] - l.sky_horizon[i]) * t);
        let q = Vec3::new(p.x, 2.5 * p.y, 0.0);
        let n = fbm(q, self.scene.sky_seed(), 300.0, 0.55, 6, band);
        let cover = l.clouds;
        let cloud = smoothstep(0.55 - 0.6 * cover, 0.85 - 0.6 * cover, 0.5 + 0.5 * n)
            * smoothstep(0.0, 0.05, elevation);
        let k = cloud as f32;
        std::array::from_fn(|i| {
            base[i] + (l.cloud_colour[i] * (0.85 + 0.3 * n as f32) - base[i]) * k
        })
    }

    /// The colour (display space, unclamped) seen along `ray` at `hit`.
    fn colour(&self, ray: &Ray, hit: &Hit) -> [f32; 3] {
        let p = ray.origin + ray.dir * hit.t;
        let band = self.band(p, hit.normal);
        let l = &self.light;
        let (albedo, emission) = match hit.surface {
            Surface::Sky => return self.sky(p, band),
            Surface::Ground => match self.scene.ground() {
                Some(g) => (g.albedo(p, band, l.wetness), [0.0; 3]),
                None => ([0.0; 3], [0.0; 3]),
            },
            Surface::Object(i) => {
                let a =
                    self.scene.objects()[i]
                        .material
                        .appearance(p, hit.normal, band, l.window_glow);
                (a.albedo, a.emission)
            }
        };
        let n = hit.normal;
        let sun = n.dot(l.sun_dir).max(0.0) as f32;
        let up = (0.5 - 0.5 * n.y) as f32;
        let fog = (p.z / (p.z + l.fog_m)) as f32;
        let mut c = [0.0f32; 3];
        for i in 0..3 {
            let light = l.ambient_sky[i] * up + l.ambient_ground[i] * (1.0 - up) + l.sun[i] * sun;
            let lit = albedo[i] * light + emission[i];
            c[i] = lit + (l.sky_horizon[i] - lit) * fog;
        }
        c
    }
}

/// The colour of pixel `(u, v)` of camera `k`, averaged over the sub-pixel
/// `offsets` grid (box filter). Geometry is always supersampled; where every
/// sample sees the same surface as the pixel centre (`centre_hit`), the
/// texture (band-limited already) is shaded once, at the centre.
fn shade_pixel(
    shader: &Shader<'_>,
    rig: &Rig,
    k: usize,
    (u, v): (f64, f64),
    centre_hit: Option<Hit>,
    offsets: &[f64],
) -> [f32; 3] {
    let clamp = |c: [f32; 3]| c.map(|x| x.clamp(0.0, 1.0));
    let grid = || {
        offsets.iter().flat_map(|&dy| {
            offsets
                .iter()
                .map(move |&dx| camera_ray(rig, k, u + dx, v + dy))
        })
    };
    let same = |h: Option<Hit>| match (h, centre_hit) {
        (Some(a), Some(b)) => a.surface == b.surface && a.normal.dot(b.normal) > 0.999,
        (None, None) => true,
        _ => false,
    };
    if grid().all(|ray| same(shader.scene.trace(&ray, 0.0))) {
        let centre = camera_ray(rig, k, u, v);
        return centre_hit.map_or([0.0; 3], |h| clamp(shader.colour(&centre, &h)));
    }
    // An edge pixel: shade every sample (tracing again is cheaper than
    // keeping the hits of the rare edge pixels).
    let weight = 1.0 / (offsets.len() * offsets.len()) as f32;
    let mut acc = [0.0f32; 3];
    for ray in grid() {
        if let Some(h) = shader.scene.trace(&ray, 0.0) {
            for (a, c) in acc.iter_mut().zip(clamp(shader.colour(&ray, &h))) {
                *a += c * weight;
            }
        }
    }
    acc
}

/// Renders every camera of `rig`: colour views (supersampled, band-limited
/// textures) and planar depth of each pixel centre. Rows run in parallel.
pub fn render(scene: &Scene, rig: &Rig, options: &RenderOptions) -> Render {
    let shader = Shader {
        scene,
        light: options.weather.lighting(),
        centre: Vec3::new(
            rig.camera_x(rig.num_views.saturating_sub(1)) / 2.0,
            0.0,
            0.0,
        ),
        focal_px: rig.focal_px,
        min_period_px: options.min_texture_period_px.max(1.0),
    };
    let s = options.supersample.max(1);
    let offsets: Vec<f64> = (0..s)
        .map(|i| (f64::from(i) + 0.5) / f64::from(s) - 0.5)
        .collect();
    let (width, height) = (rig.width, rig.height);
    let w = width as usize;
    let mut views = Vec::with_capacity(rig.num_views);
    let mut depth = Vec::with_capacity(rig.num_views);
    for k in 0..rig.num_views {
        let mut view = RgbImage::new(width, height);
        let mut z = FloatImage::new(width, height);
        if w > 0 {
            view.par_chunks_mut(w * 3)
                .zip(z.par_chunks_mut(w))
                .enumerate()
                .for_each(|(row, (rgb, zrow))| {
                    let v = row as f64;
                    for (x, (px, zv)) in rgb.chunks_exact_mut(3).zip(zrow.iter_mut()).enumerate() {
                        let u = x as f64;
                        let centre = camera_ray(rig, k, u, v);
                        let centre_hit = scene.trace(&centre, 0.0);
                        *zv = centre_hit.map_or(f32::INFINITY, |h| h.t as f32);
                        let c = shade_pixel(&shader, rig, k, (u, v), centre_hit, &offsets);
                        for (p, c) in px.iter_mut().zip(c) {
                            *p = (c * 255.0 + 0.5) as u8;
                        }
                    }
                });
        }
        views.push(view);
        depth.push(z);
    }
    Render { views, depth }
}

/// The exact disparity (px) of `depth` for a one-baseline step,
/// `f * B / z` on the depth's own grid; the sky (1000 m) keeps its small
/// finite disparity. Multiply by `k` for a `k`-baseline pair.
pub fn one_step_disparity(depth: &FloatImage, rig: &Rig) -> FloatImage {
    depth_to_disparity(depth, rig, 0, 1, f32::INFINITY)
}
