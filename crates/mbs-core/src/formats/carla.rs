//! CARLA's RGB-encoded depth (conventions §3): 8-bit RGB, R least significant,
//! `z_m = 1000 * (R + 256 G + 65536 B) / (256^3 - 1)`. Sky decodes to about
//! 1000 m.

use rayon::prelude::*;

use crate::{FloatImage, RgbImage};

/// The largest code, `256^3 - 1`.
pub const MAX_CODE: u32 = (1 << 24) - 1;
/// The far plane of CARLA's depth camera, in metres.
pub const FAR_PLANE_M: f64 = 1000.0;
/// One quantisation step of the encoding, in metres (about 6e-5 m).
pub const QUANTUM_M: f64 = FAR_PLANE_M / MAX_CODE as f64;

/// The 24-bit code of one pixel.
pub fn code(rgb: [u8; 3]) -> u32 {
    u32::from(rgb[0]) | (u32::from(rgb[1]) << 8) | (u32::from(rgb[2]) << 16)
}

/// Depth in metres of one code, exactly as CARLA's formula (in f64,
/// rounded once to f32).
pub fn decode_code(code: u32) -> f32 {
    (f64::from(code) * FAR_PLANE_M / f64::from(MAX_CODE)) as f32
}

/// Decodes a CARLA depth image into metres, in parallel over rows.
pub fn decode_depth(rgb: &RgbImage) -> FloatImage {
    let (width, height) = rgb.dimensions();
    let mut out = FloatImage::new(width, height);
    let row = width.max(1) as usize;
    out.par_chunks_mut(row)
        .zip(rgb.par_chunks(row * 3))
        .for_each(|(dst, src)| {
            for (d, px) in dst.iter_mut().zip(src.chunks_exact(3)) {
                *d = decode_code(code([px[0], px[1], px[2]]));
            }
        });
    out
}

/// The nearest code for a depth in metres; non-finite or out-of-range depth
/// is clamped to the far plane (sky) or to 0.
pub fn encode_value(depth_m: f32) -> [u8; 3] {
    let scaled = f64::from(depth_m) / FAR_PLANE_M * f64::from(MAX_CODE);
    let code = if depth_m.is_nan() {
        MAX_CODE
    } else {
        scaled.round().clamp(0.0, f64::from(MAX_CODE)) as u32
    };
    [
        (code & 0xff) as u8,
        ((code >> 8) & 0xff) as u8,
        (code >> 16) as u8,
    ]
}

/// Encodes a depth map in metres as a CARLA depth image.
pub fn encode_depth(depth: &FloatImage) -> RgbImage {
    let (width, height) = depth.dimensions();
    let mut out = RgbImage::new(width, height);
    let row = width.max(1) as usize;
    out.par_chunks_mut(row * 3)
        .zip(depth.par_chunks(row))
        .for_each(|(dst, src)| {
            for (px, &z) in dst.chunks_exact_mut(3).zip(src) {
                px.copy_from_slice(&encode_value(z));
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The formula of conventions §3, written as literally as possible.
    fn formula(r: u8, g: u8, b: u8) -> f32 {
        (1000.0 * (f64::from(r) + 256.0 * f64::from(g) + 65536.0 * f64::from(b))
            / (256.0f64.powi(3) - 1.0)) as f32
    }

    #[test]
    fn boundary_codes_decode_exactly() {
        assert_eq!(decode_code(0), 0.0);
        assert_eq!(decode_code(1), formula(1, 0, 0));
        assert_eq!(decode_code(MAX_CODE), 1000.0);
        assert_eq!(decode_code(code([255, 255, 255])), formula(255, 255, 255));
        assert_eq!(decode_code(code([0, 0, 1])), formula(0, 0, 1));
    }

    #[test]
    fn every_code_decodes_exactly_as_the_formula() {
        for c in 0..=MAX_CODE {
            let px = [(c & 0xff) as u8, ((c >> 8) & 0xff) as u8, (c >> 16) as u8];
            assert_eq!(
                decode_code(code(px)),
                formula(px[0], px[1], px[2]),
                "code {c}"
            );
        }
    }

    #[test]
    fn image_decode_uses_r_as_least_significant() {
        let rgb = RgbImage::from_raw(2, 1, vec![1, 0, 0, 0, 0, 1]).unwrap();
        let depth = decode_depth(&rgb);
        assert_eq!(depth.as_raw(), &vec![formula(1, 0, 0), formula(0, 0, 1)]);
    }

    proptest! {
        #[test]
        fn encode_decode_round_trip_within_one_quantum(z in 0.0f32..1000.0) {
            let back = decode_code(code(encode_value(z)));
            prop_assert!((f64::from(back) - f64::from(z)).abs() <= QUANTUM_M, "{} -> {}", z, back);
        }

        #[test]
        fn image_round_trip(values in proptest::collection::vec(0.0f32..1000.0, 12)) {
            let depth = FloatImage::from_raw(4, 3, values).unwrap();
            let back = decode_depth(&encode_depth(&depth));
            for (a, b) in depth.as_raw().iter().zip(back.as_raw()) {
                prop_assert!((f64::from(*a) - f64::from(*b)).abs() <= QUANTUM_M);
            }
        }
    }
}
