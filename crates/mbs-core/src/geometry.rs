//! Rig geometry (conventions §2): N rectified pinhole cameras on one horizontal line,
//! camera `k` at `x = k * B`, one focal length and principal point for all.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::FloatImage;

/// A multi-baseline rig of rectified cameras on one horizontal line.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rig {
    /// Number of cameras, indexed 0..N-1 from left to right.
    pub num_views: usize,
    /// Distance between neighbouring cameras, in metres.
    pub baseline_m: f64,
    /// Focal length in pixels (the same for all cameras).
    pub focal_px: f64,
    /// Principal point, column (pixels).
    pub cx: f64,
    /// Principal point, row (pixels).
    pub cy: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// On which side of the reference camera a target camera lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// The target is left of the reference: a reference pixel at `x` is seen at `x + d`.
    Left,
    /// The target is right of the reference: a reference pixel at `x` is seen at `x - d`.
    Right,
}

impl Side {
    /// The side of camera `target` as seen from camera `reference`
    /// (`None` when they are the same camera).
    pub fn of(reference: usize, target: usize) -> Option<Side> {
        match target.cmp(&reference) {
            std::cmp::Ordering::Less => Some(Side::Left),
            std::cmp::Ordering::Greater => Some(Side::Right),
            std::cmp::Ordering::Equal => None,
        }
    }

    /// The signed column shift from a reference pixel to its match in the
    /// target, for a disparity magnitude `d`.
    pub fn shift(self, d: f32) -> f32 {
        match self {
            Side::Left => d,
            Side::Right => -d,
        }
    }
}

impl Rig {
    /// The MBS20K rig: 5 cameras, B = 0.5 m, f = 480 px, 960 x 540 images.
    pub fn mbs20k() -> Rig {
        Rig::centred(5, 0.5, 480.0, 960, 540)
    }

    /// A rig whose principal point is the image centre.
    pub fn centred(
        num_views: usize,
        baseline_m: f64,
        focal_px: f64,
        width: u32,
        height: u32,
    ) -> Rig {
        Rig {
            num_views,
            baseline_m,
            focal_px,
            cx: (f64::from(width) - 1.0) / 2.0,
            cy: (f64::from(height) - 1.0) / 2.0,
            width,
            height,
        }
    }

    /// The x position of camera `k` in metres.
    pub fn camera_x(&self, k: usize) -> f64 {
        k as f64 * self.baseline_m
    }

    /// The x positions of all cameras in metres.
    pub fn camera_positions(&self) -> Vec<f64> {
        (0..self.num_views).map(|k| self.camera_x(k)).collect()
    }

    /// `f * |x_t - x_r|`: the disparity (px) of a point at 1 m depth for the
    /// pair (reference, target); disparity = this / depth.
    pub fn disparity_scale(&self, reference: usize, target: usize) -> f64 {
        self.focal_px * (self.camera_x(target) - self.camera_x(reference)).abs()
    }

    /// Teacher/student rescaling ratio (paper eq. 4):
    /// `r = |x_ts - x_r| / |x_tt - x_r|`, so that `d_s = r * d_t`.
    pub fn baseline_ratio(&self, reference: usize, student: usize, teacher: usize) -> f64 {
        let dist = |t: usize| (self.camera_x(t) - self.camera_x(reference)).abs();
        dist(student) / dist(teacher)
    }
}

/// Disparity (px) of a point at planar depth `depth_m` for a pair whose
/// [`Rig::disparity_scale`] is `scale`. Depth that is not finite, not positive
/// or beyond `max_depth_m` gives `+inf` (invalid).
pub fn depth_to_disparity_value(depth_m: f32, scale: f64, max_depth_m: f32) -> f32 {
    // f32 division (correctly rounded, so within one ulp of the f64 result);
    // the branch-free select lets whole rows vectorise.
    let disparity = scale as f32 / depth_m;
    if depth_m > 0.0 && depth_m <= max_depth_m && depth_m.is_finite() {
        disparity
    } else {
        f32::INFINITY
    }
}

/// Planar depth (m) for a disparity `disparity_px` for a pair whose
/// [`Rig::disparity_scale`] is `scale`. Non-finite or non-positive disparity
/// gives `+inf` (invalid).
pub fn disparity_to_depth_value(disparity_px: f32, scale: f64) -> f32 {
    if disparity_px.is_finite() && disparity_px > 0.0 {
        (scale / f64::from(disparity_px)) as f32
    } else {
        f32::INFINITY
    }
}

/// `depth` with every value beyond `max_depth_m` marked invalid (`+inf`).
pub fn limit_depth(depth: &FloatImage, max_depth_m: f32) -> FloatImage {
    let mut limited = depth.clone();
    limited
        .iter_mut()
        .filter(|z| **z > max_depth_m)
        .for_each(|z| *z = f32::INFINITY);
    limited
}

/// Converts a depth map of camera `reference` into the disparity map of the
/// pair (`reference`, `target`); depth beyond `max_depth_m` becomes invalid.
pub fn depth_to_disparity(
    depth: &FloatImage,
    rig: &Rig,
    reference: usize,
    target: usize,
    max_depth_m: f32,
) -> FloatImage {
    let scale = rig.disparity_scale(reference, target);
    map_pixels(depth, |z| depth_to_disparity_value(z, scale, max_depth_m))
}

/// Converts a disparity map of the pair (`reference`, `target`) into the
/// depth map of camera `reference`.
pub fn disparity_to_depth(
    disparity: &FloatImage,
    rig: &Rig,
    reference: usize,
    target: usize,
) -> FloatImage {
    let scale = rig.disparity_scale(reference, target);
    map_pixels(disparity, |d| disparity_to_depth_value(d, scale))
}

/// Applies `f` to every pixel, in parallel over rows.
fn map_pixels(input: &FloatImage, f: impl Fn(f32) -> f32 + Sync) -> FloatImage {
    let (width, height) = input.dimensions();
    let mut out = FloatImage::new(width, height);
    let row = width as usize;
    out.par_chunks_mut(row.max(1))
        .zip(input.par_chunks(row.max(1)))
        .for_each(|(dst, src)| dst.iter_mut().zip(src).for_each(|(d, &s)| *d = f(s)));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mbs20k_rig_matches_spec() {
        let rig = Rig::mbs20k();
        assert_eq!(rig.camera_positions(), vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        // f * B = 240 px at 1 m for neighbours, 960 for the outer pair.
        assert_eq!(rig.disparity_scale(0, 1), 240.0);
        assert_eq!(rig.disparity_scale(4, 0), 960.0);
    }

    #[test]
    fn baseline_ratio_follows_eq4() {
        let rig = Rig::mbs20k();
        // reference 2, student target 0 (2 steps), teacher target 3 (1 step).
        assert_eq!(rig.baseline_ratio(2, 0, 3), 2.0);
        assert_eq!(rig.baseline_ratio(2, 3, 4), 0.5);
    }

    #[test]
    fn depth_disparity_round_trip_and_invalid() {
        let rig = Rig::mbs20k();
        let depth = FloatImage::from_raw(4, 1, vec![10.0, 250.0, 0.0, f32::NAN]).unwrap();
        let disp = depth_to_disparity(&depth, &rig, 0, 2, 200.0);
        assert_eq!(disp.as_raw()[0], 48.0); // 480 * 1.0 / 10
        assert_eq!(depth_to_disparity_value(3.0, 240.0, 200.0), 80.0);
        assert!(disp.as_raw()[1..].iter().all(|d| *d == f32::INFINITY));
        let back = disparity_to_depth(&disp, &rig, 0, 2);
        assert!((back.as_raw()[0] - 10.0).abs() < 1e-5);
        assert!(back.as_raw()[1..].iter().all(|d| *d == f32::INFINITY));
    }

    #[test]
    fn side_shift_follows_spec() {
        assert_eq!(Side::of(1, 2), Some(Side::Right));
        assert_eq!(Side::of(1, 0), Some(Side::Left));
        assert_eq!(Side::of(1, 1), None);
        assert_eq!(Side::Right.shift(3.0), -3.0);
        assert_eq!(Side::Left.shift(3.0), 3.0);
    }
}
