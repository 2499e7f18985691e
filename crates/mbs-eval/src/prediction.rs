//! What a protocol does to a prediction before comparing it
//! ([`PredictionRule`]): the size it must have, the KITTI devkits' hole
//! filling, ETH3D's not-estimated pixels, and MiddEval3 evaldisp's
//! upsampling and clipping.

use mbs_core::FloatImage;

use crate::protocol::{PredictionRule, ProtocolError};
use crate::sums::MetricsError;

/// evaldisp's `maxdisp` when none is given (evaldisp.cpp `main`).
const EVALDISP_DEFAULT_MAXDISP: f32 = 99999.0;

/// A prediction on the ground truth's grid, with which of its pixels count
/// as estimated.
#[derive(Debug)]
pub(crate) struct Prepared {
    /// The values compared, row-major at the ground truth's size.
    pub values: Vec<f32>,
    /// Whether the prediction had a value there (the density's count).
    pub estimated: Vec<bool>,
}

/// `prediction` as `rule` compares it with a ground truth of `size`;
/// `bound` is the scene's `ndisp` at the ground truth's resolution.
pub(crate) fn prepare(
    rule: PredictionRule,
    prediction: &FloatImage,
    size: (u32, u32),
    bound: Option<u32>,
) -> Result<Prepared, ProtocolError> {
    if rule == PredictionRule::MiddleburyEvaldisp {
        return evaldisp(prediction, size, bound);
    }
    if prediction.dimensions() != size {
        return Err(MetricsError::SizeMismatch {
            what: "the prediction",
            expected: size,
            actual: prediction.dimensions(),
        }
        .into());
    }
    let raw = prediction.as_raw();
    let width = size.0 as f32;
    let estimated: Vec<bool> = match rule {
        // main.cc:398-401: NaN, inf, d > width or d < -width.
        PredictionRule::Eth3dEstimated => raw
            .iter()
            .map(|d| d.is_finite() && d.abs() <= width)
            .collect(),
        // io_disp.h isValid: data >= 0, where a PNG 0 reads as -1.
        PredictionRule::KittiBackground => raw.iter().map(|d| kitti_valid(*d)).collect(),
        _ => raw.iter().map(|d| d.is_finite()).collect(),
    };
    let values = match rule {
        PredictionRule::KittiBackground => interpolate_background(raw, size.0 as usize),
        _ => raw.clone(),
    };
    Ok(Prepared { values, estimated })
}

/// Whether the KITTI devkit holds a value valid: it reads the submission's
/// 16-bit PNG, where a value is `round(d * 256)` and 0 is a hole, so a
/// value below 1/512 px (0 included), a negative one or a non-finite one
/// is a hole.
fn kitti_valid(d: f32) -> bool {
    d.is_finite() && (d * 256.0).round() >= 1.0
}

/// The KITTI devkits' `interpolateBackground()` (io_disp.h) on a row-major
/// map `width` wide: in each row, a run of holes with a valid pixel on
/// both sides takes the smaller (background) of the two; the row's ends
/// take its first and last valid values; then each column's top and
/// bottom take its first and last valid values. Holes are the values a
/// KITTI PNG stores as 0 (see `kitti_valid`); a hole nothing reaches stays
/// `-1`, the devkit's
/// invalid value, and is compared as `-1`.
pub fn interpolate_background(map: &[f32], width: usize) -> Vec<f32> {
    let mut d: Vec<f32> = map
        .iter()
        .map(|&v| if kitti_valid(v) { v } else { -1.0 })
        .collect();
    if width == 0 {
        return d;
    }
    for row in d.chunks_mut(width) {
        fill_row(row);
    }
    let height = d.len() / width;
    for u in 0..width {
        let column: Vec<usize> = (0..height).map(|v| v * width + u).collect();
        if let Some(first) = column.iter().position(|&i| d[i] >= 0.0) {
            let value = d[column[first]];
            column[..first].iter().for_each(|&i| d[i] = value);
        }
        if let Some(last) = column.iter().rposition(|&i| d[i] >= 0.0) {
            let value = d[column[last]];
            column[last + 1..].iter().for_each(|&i| d[i] = value);
        }
    }
    d
}

/// One row of [`interpolate_background`].
fn fill_row(row: &mut [f32]) {
    let mut count = 0;
    for u in 0..row.len() {
        if row[u] >= 0.0 {
            // A run u1..=u2 that starts after column 0 (u2 < width - 1
            // always holds: u is valid).
            if count >= 1 && u > count {
                let (u1, u2) = (u - count, u - 1);
                let fill = row[u1 - 1].min(row[u2 + 1]);
                row[u1..=u2].fill(fill);
            }
            count = 0;
        } else {
            count += 1;
        }
    }
    if let Some(first) = row.iter().position(|&v| v >= 0.0) {
        let value = row[first];
        row[..first].fill(value);
    }
    if let Some(last) = row.iter().rposition(|&v| v >= 0.0) {
        let value = row[last];
        row[last + 1..].fill(value);
    }
}

/// evaldisp.cpp's `evaldisp`: the prediction upsampled by repeating pixels
/// to the ground truth's `size` (the factor 1, 2 or 4) and multiplied by
/// the factor; `+inf` (and NaN, which evaldisp leaves undefined) invalid,
/// kept as `+inf`; valid values clipped to `[0, bound]` (`bound`: ndisp at
/// the ground truth's resolution, else 99999 × the factor).
fn evaldisp(
    prediction: &FloatImage,
    size: (u32, u32),
    bound: Option<u32>,
) -> Result<Prepared, ProtocolError> {
    let (width, height) = prediction.dimensions();
    let scale = size.0.checked_div(width).unwrap_or(0);
    if !matches!(scale, 1 | 2 | 4) || scale * width != size.0 || scale * height != size.1 {
        return Err(ProtocolError::Scale {
            expected: size,
            actual: (width, height),
        });
    }
    let factor = scale as f32;
    let max = bound.map_or(factor * EVALDISP_DEFAULT_MAXDISP, |n| n as f32);
    let count = size.0 as usize * size.1 as usize;
    let (mut values, mut estimated) = (Vec::with_capacity(count), Vec::with_capacity(count));
    for y in 0..size.1 {
        for x in 0..size.0 {
            let d = factor * prediction.get_pixel(x / scale, y / scale).0[0];
            let valid = d != f32::INFINITY && !d.is_nan();
            // __max(0, __min(maxd, d)): -inf becomes 0.
            values.push(if valid {
                d.min(max).max(0.0)
            } else {
                f32::INFINITY
            });
            estimated.push(valid);
        }
    }
    Ok(Prepared { values, estimated })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn background_interpolation_follows_the_devkit() {
        // Row 0: a leading hole (extrapolated), an inner run (the smaller
        // neighbour) and a trailing hole (extrapolated); row 1: all holes,
        // filled from the column above; negative values are holes.
        let map = [
            f32::NAN,
            5.0,
            -2.0,
            f32::INFINITY,
            3.0,
            f32::NAN, //
            -1.0,
            f32::NAN,
            -3.0,
            f32::NAN,
            f32::NAN,
            f32::NAN,
        ];
        let filled = interpolate_background(&map, 6);
        assert_eq!(
            filled,
            [5.0, 5.0, 3.0, 3.0, 3.0, 3.0, 5.0, 5.0, 3.0, 3.0, 3.0, 3.0]
        );
        // A map with no valid value stays at the devkit's -1.
        assert_eq!(interpolate_background(&[f32::NAN; 4], 2), [-1.0; 4]);
        // A hole row between two valid rows is not reached by the column
        // pass, which only extrapolates upwards and downwards.
        let middle = interpolate_background(&[1.0, f32::NAN, 2.0], 1);
        assert_eq!(middle, [1.0, -1.0, 2.0]);
    }

    #[test]
    fn evaldisp_upsamples_scales_and_clips() {
        let prediction = FloatImage::from_raw(2, 1, vec![30.0, f32::NEG_INFINITY]).unwrap();
        let prepared = evaldisp(&prediction, (4, 2), Some(50)).unwrap();
        // x2: 60 clipped to ndisp 50; -inf clipped to 0.
        assert_eq!(
            prepared.values,
            [50.0, 50.0, 0.0, 0.0, 50.0, 50.0, 0.0, 0.0]
        );
        assert!(prepared.estimated.iter().all(|&e| e));
        let holes = FloatImage::from_raw(1, 1, vec![f32::INFINITY]).unwrap();
        assert_eq!(evaldisp(&holes, (1, 1), None).unwrap().estimated, [false]);
        let err = evaldisp(&prediction, (6, 3), None).unwrap_err();
        assert!(matches!(err, ProtocolError::Scale { .. }), "{err}");
        assert!(
            evaldisp(&prediction, (4, 3), None).is_err(),
            "heights must match too"
        );
    }

    #[test]
    fn eth3d_estimates_within_the_image_width() {
        let prediction = FloatImage::from_raw(3, 1, vec![3.0, -3.5, f32::NAN]).unwrap();
        let prepared = prepare(PredictionRule::Eth3dEstimated, &prediction, (3, 1), None).unwrap();
        assert_eq!(prepared.estimated, [true, false, false]);
        let err = prepare(PredictionRule::AsIs, &prediction, (2, 1), None).unwrap_err();
        assert!(
            err.to_string().contains("the prediction is (3, 1)"),
            "{err}"
        );
    }
}
