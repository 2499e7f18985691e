//! Band-limited procedural noise: 3D gradient (Perlin) noise from an integer
//! hash, summed over octaves that fade out before their lattice period falls
//! below a given number of pixels. Only `+ - * /`, `floor` and integer
//! arithmetic are used, so results are bit-identical on every IEEE machine.

use crate::vec3::Vec3;

/// A 32-bit integer hash of a lattice point and a seed.
pub(crate) fn hash3(x: i64, y: i64, z: i64, seed: u32) -> u32 {
    let mut h = seed
        ^ (x as u32).wrapping_mul(0x8da6_b343)
        ^ (y as u32).wrapping_mul(0xd816_3841)
        ^ (z as u32).wrapping_mul(0xcb1a_b31f);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7feb_352d);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846c_a68b);
    h ^= h >> 16;
    h
}

/// A hash mapped to [0, 1).
pub(crate) fn hash_unit(x: i64, y: i64, z: i64, seed: u32) -> f64 {
    f64::from(hash3(x, y, z, seed) >> 8) / f64::from(1u32 << 24)
}

fn grad(h: u32, x: f64, y: f64, z: f64) -> f64 {
    // The 12 cube-edge directions of improved Perlin noise (4 repeated).
    match h & 15 {
        0 | 12 => x + y,
        1 | 13 => -x + y,
        2 => x - y,
        3 => -x - y,
        4 => x + z,
        5 => -x + z,
        6 => x - z,
        7 => -x - z,
        8 => y + z,
        9 | 14 => -y + z,
        10 => y - z,
        _ => -y - z,
    }
}

fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

/// Gradient noise with unit lattice spacing, roughly in [-1, 1], zero mean.
pub(crate) fn perlin(p: Vec3, seed: u32) -> f64 {
    let (fx, fy, fz) = (p.x.floor(), p.y.floor(), p.z.floor());
    let (ix, iy, iz) = (fx as i64, fy as i64, fz as i64);
    let (x, y, z) = (p.x - fx, p.y - fy, p.z - fz);
    let (u, v, w) = (fade(x), fade(y), fade(z));
    let g = |dx: i64, dy: i64, dz: i64| {
        grad(
            hash3(ix + dx, iy + dy, iz + dz, seed),
            x - dx as f64,
            y - dy as f64,
            z - dz as f64,
        )
    };
    lerp(
        lerp(
            lerp(g(0, 0, 0), g(1, 0, 0), u),
            lerp(g(0, 1, 0), g(1, 1, 0), u),
            v,
        ),
        lerp(
            lerp(g(0, 0, 1), g(1, 0, 1), u),
            lerp(g(0, 1, 1), g(1, 1, 1), u),
            v,
        ),
        w,
    )
}

/// Cubic smoothstep from 0 at `a` to 1 at `b` (`a < b`).
pub(crate) fn smoothstep(a: f64, b: f64, x: f64) -> f64 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// How an octave's weight depends on its lattice period on screen.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Band {
    /// World size of one pixel at the surface point (metres).
    pub(crate) footprint_m: f64,
    /// Octaves whose period is below this many pixels are dropped; they
    /// fade in between this and twice this.
    pub(crate) min_period_px: f64,
}

impl Band {
    /// Weight in [0, 1] of detail with the given world period.
    pub(crate) fn weight(self, period_m: f64) -> f64 {
        let period_px = period_m / self.footprint_m;
        smoothstep(self.min_period_px, 2.0 * self.min_period_px, period_px)
    }
}

/// Fractal sum of `octaves` octaves of gradient noise from `base_period_m`
/// down, each half the period and `gain` times the amplitude of the
/// previous, faded by `band`. The sum is normalised by the root of the summed
/// squared weights of the octaves kept, so contrast stays about the same
/// when fine octaves are dropped (up to a 4x boost: beyond that, far surfaces
/// fade to flat). Roughly in [-1, 1].
pub(crate) fn fbm(
    p: Vec3,
    seed: u32,
    base_period_m: f64,
    gain: f64,
    octaves: u32,
    band: Band,
) -> f64 {
    let mut period = base_period_m;
    let mut amp = 1.0;
    let mut sum = 0.0;
    let mut kept = 0.0;
    let mut full = 0.0;
    for octave in 0..octaves {
        full += amp * amp;
        let w = band.weight(period);
        if w > 0.0 {
            // Offset each octave so that lattice points do not line up.
            let shift = f64::from(octave) * 17.371;
            let q = Vec3::new(p.x + shift, p.y - shift, p.z + shift) * (1.0 / period);
            sum += amp * w * perlin(q, seed.wrapping_add(octave));
            kept += (amp * w) * (amp * w);
        }
        period *= 0.5;
        amp *= gain;
    }
    // Perlin noise rarely exceeds 0.5 in magnitude: rescale to about [-1, 1].
    2.0 * sum / kept.max(full / 16.0).sqrt()
}

/// A periodic pulse of height 1 occupying the fraction `duty` of each period
/// (centred in the period), with edges smoothed over `blur` metres and faded
/// to its mean `duty` once `blur` approaches the period.
pub(crate) fn pulse(x: f64, period: f64, duty: f64, blur: f64) -> f64 {
    let fade = smoothstep(0.15 * period, 0.3 * period, blur);
    if fade >= 1.0 {
        return duty;
    }
    let f = x / period;
    let u = (f - f.floor()) * period;
    let (lo, hi) = (0.5 * (1.0 - duty) * period, 0.5 * (1.0 + duty) * period);
    let b = blur.max(1e-6);
    let v = smoothstep(lo - b, lo + b, u) * (1.0 - smoothstep(hi - b, hi + b, u));
    v + (duty - v) * fade
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perlin_is_zero_on_lattice_and_bounded() {
        assert_eq!(perlin(Vec3::new(3.0, -2.0, 7.0), 5), 0.0);
        let mut max: f64 = 0.0;
        for i in 0..1000 {
            let t = f64::from(i) * 0.0731;
            max = max.max(perlin(Vec3::new(t, 1.3 * t, -0.7 * t), 1).abs());
        }
        assert!(max > 0.2 && max <= 1.0, "max {max}");
    }

    #[test]
    fn fbm_drops_octaves_below_the_band() {
        let p = Vec3::new(1.234, 5.678, 9.1011);
        let coarse = Band {
            footprint_m: 100.0,
            min_period_px: 3.0,
        };
        // Every octave is far below 3 px: nothing is left.
        assert_eq!(fbm(p, 3, 8.0, 0.5, 9, coarse), 0.0);
        let fine = Band {
            footprint_m: 1e-4,
            min_period_px: 3.0,
        };
        assert_ne!(fbm(p, 3, 8.0, 0.5, 9, fine), 0.0);
    }

    #[test]
    fn pulse_shape_and_fade() {
        assert!((pulse(0.5, 1.0, 0.5, 0.01) - 1.0).abs() < 1e-12);
        assert!(pulse(0.05, 1.0, 0.5, 0.01).abs() < 1e-12);
        assert_eq!(pulse(0.5, 1.0, 0.5, 1.0), 0.5);
    }
}
