//! Colour maps for looking at disparity and depth maps.

use mbs_core::{FloatImage, RgbImage};

/// Google's Turbo colour map at `t` in `[0, 1]` (polynomial fit, Mikhailov
/// 2019): dark at 0, blue, green, yellow, to dark red at 1.
pub fn turbo(t: f32) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let poly = |c: [f32; 6]| {
        let v = c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5]))));
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    };
    [
        poly([
            0.135_721_4,
            4.615_392_6,
            -42.660_32,
            132.131_08,
            -152.942_4,
            59.286_38,
        ]),
        poly([
            0.091_402_61,
            2.194_188_4,
            4.842_966_6,
            -14.185_033,
            4.277_298_6,
            2.829_566,
        ]),
        poly([
            0.106_673_3,
            12.641_946,
            -60.582_05,
            110.362_77,
            -89.903_11,
            27.348_25,
        ]),
    ]
}

/// The top of the colour scale for `maps`: their largest finite value, at
/// least 1 (so an empty or all-zero map still gets a scale).
pub fn disparity_scale<'a>(maps: impl IntoIterator<Item = &'a FloatImage>) -> f32 {
    maps.into_iter()
        .flat_map(|d| d.iter())
        .filter(|d| d.is_finite())
        .fold(1.0f32, |m, &d| m.max(d))
}

/// A colour picture of a disparity map: Turbo from 0 (blue, far) to `max`
/// (red, near); invalid (non-finite) pixels are black.
pub fn colorize_disparity(disparity: &FloatImage, max: f32) -> RgbImage {
    let scale = if max > 0.0 { 1.0 / max } else { 0.0 };
    RgbImage::from_fn(disparity.width(), disparity.height(), |x, y| {
        let d = disparity.get_pixel(x, y).0[0];
        image::Rgb(if d.is_finite() {
            turbo(d * scale)
        } else {
            [0, 0, 0]
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turbo_runs_from_blue_to_red() {
        let [r0, _, b0] = turbo(0.15);
        let [r1, _, b1] = turbo(0.9);
        assert!(b0 > r0 && r1 > b1, "{:?} {:?}", turbo(0.15), turbo(0.9));
        // The middle is green-ish.
        let [r, g, b] = turbo(0.5);
        assert!(g > r && g > b, "{r} {g} {b}");
    }

    #[test]
    fn invalid_pixels_are_black() {
        let d = FloatImage::from_raw(2, 1, vec![f32::INFINITY, 4.0]).unwrap();
        let c = colorize_disparity(&d, 4.0);
        assert_eq!(c.get_pixel(0, 0).0, [0, 0, 0]);
        assert_eq!(c.get_pixel(1, 0).0, turbo(1.0));
    }
}
