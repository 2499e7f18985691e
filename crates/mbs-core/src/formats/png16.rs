//! 16-bit greyscale PNG maps: KITTI disparity (`d = v / 256`, `0` = invalid)
//! and depth in millimetres (`z = v / 1000` m, `0` = invalid).

use std::path::Path;

use image::{ImageBuffer, Luma};

use crate::FloatImage;
use crate::atomic::write_atomic;
use crate::error::{FormatError, Result};

/// A 16-bit greyscale image.
pub type Gray16Image = ImageBuffer<Luma<u16>, Vec<u16>>;

/// Units per pixel of disparity in KITTI PNGs.
pub const KITTI_DISPARITY_SCALE: f32 = 256.0;
/// Units per metre of depth in millimetre PNGs.
pub const DEPTH_MM_SCALE: f32 = 1000.0;

/// Reads a 16-bit greyscale PNG (refusing 8-bit or colour files).
pub fn read_gray16(path: &Path) -> Result<Gray16Image> {
    let image = super::open_image(path)?;
    match image {
        image::DynamicImage::ImageLuma16(gray) => Ok(gray),
        other => Err(FormatError::invalid(
            path,
            format!("expected a 16-bit greyscale PNG, found {:?}", other.color()),
        )),
    }
}

/// Writes a 16-bit greyscale PNG atomically.
pub fn write_gray16(path: &Path, image: &Gray16Image) -> Result<()> {
    write_atomic(path, |w| {
        image
            .write_with_encoder(super::png_encoder(w))
            .map_err(std::io::Error::other)
    })
}

/// Decodes 8- or 16-bit integer codes `v` into floats `v / scale`, with
/// `0` -> `+inf`.
pub fn decode_scaled<P>(codes: &ImageBuffer<Luma<P>, Vec<P>>, scale: f32) -> FloatImage
where
    P: image::Primitive + Into<f32>,
{
    let data = codes
        .as_raw()
        .iter()
        .map(|&v| {
            let v: f32 = v.into();
            if v == 0.0 { f32::INFINITY } else { v / scale }
        })
        .collect();
    // Same dimensions and one sample per pixel, so the length matches.
    FloatImage::from_raw(codes.width(), codes.height(), data).expect("same size as the input")
}

/// Encodes floats as `round(x * scale)`. Invalid values (non-finite,
/// negative, or too large for 16 bits) become `0`; valid values that would
/// round to `0` are stored as `1` so they stay valid.
pub fn encode_scaled(values: &FloatImage, scale: f32) -> Gray16Image {
    let max = f32::from(u16::MAX) + 1.0;
    let data = values
        .as_raw()
        .iter()
        .map(|&x| {
            // Adding 0.5 and truncating rounds the non-negative values that
            // pass the check; NaN fails every comparison.
            let scaled = x * scale + 0.5;
            if x >= 0.0 && scaled < max {
                (scaled as u16).max(1)
            } else {
                0
            }
        })
        .collect();
    // Same dimensions and one sample per pixel, so the length matches.
    Gray16Image::from_raw(values.width(), values.height(), data).expect("same size as the input")
}

/// Reads a KITTI disparity PNG: `d = v / 256`, `0` -> `+inf` (invalid).
pub fn read_kitti_disparity(path: &Path) -> Result<FloatImage> {
    Ok(decode_scaled(&read_gray16(path)?, KITTI_DISPARITY_SCALE))
}

/// Writes a KITTI disparity PNG. Disparities above 255.996 px, negative or
/// non-finite are stored as `0` (invalid).
pub fn write_kitti_disparity(path: &Path, disparity: &FloatImage) -> Result<()> {
    write_gray16(path, &encode_scaled(disparity, KITTI_DISPARITY_SCALE))
}

/// Reads a 16-bit millimetre depth PNG into metres, `0` -> `+inf`.
pub fn read_depth_mm(path: &Path) -> Result<FloatImage> {
    Ok(decode_scaled(&read_gray16(path)?, DEPTH_MM_SCALE))
}

/// Writes depth in metres as a 16-bit millimetre PNG; depth beyond 65.535 m
/// or invalid is stored as `0`.
pub fn write_depth_mm(path: &Path, depth: &FloatImage) -> Result<()> {
    write_gray16(path, &encode_scaled(depth, DEPTH_MM_SCALE))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kitti_round_trip_is_exact_on_the_grid_and_keeps_invalid() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.png");
        let values = vec![
            0.5,
            12.25,
            255.0,
            f32::INFINITY,
            1.0 / 256.0,
            100.0 + 3.0 / 256.0,
        ];
        let disp = FloatImage::from_raw(3, 2, values.clone()).unwrap();
        write_kitti_disparity(&path, &disp).unwrap();
        let back = read_kitti_disparity(&path).unwrap();
        assert_eq!(back.as_raw(), &values);
    }

    #[test]
    fn kitti_quantisation_error_is_at_most_half_a_step() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("q.png");
        let disp = FloatImage::from_fn(50, 3, |x, y| {
            Luma([x as f32 * 3.917 + y as f32 * 0.0131 + 0.01])
        });
        write_kitti_disparity(&path, &disp).unwrap();
        let back = read_kitti_disparity(&path).unwrap();
        for (a, b) in disp.as_raw().iter().zip(back.as_raw()) {
            assert!((a - b).abs() <= 0.5 / 256.0 + 1e-6, "{a} vs {b}");
        }
    }

    #[test]
    fn out_of_range_values_become_invalid() {
        let disp = FloatImage::from_raw(4, 1, vec![-1.0, 300.0, f32::NAN, 1e-6]).unwrap();
        let codes = encode_scaled(&disp, KITTI_DISPARITY_SCALE);
        assert_eq!(codes.as_raw(), &vec![0, 0, 0, 1]);
    }

    #[test]
    fn depth_mm_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("z.png");
        let depth = FloatImage::from_raw(3, 1, vec![1.234, 65.535, 70.0]).unwrap();
        write_depth_mm(&path, &depth).unwrap();
        let back = read_depth_mm(&path).unwrap();
        assert_eq!(back.as_raw()[0], 1.234);
        assert_eq!(back.as_raw()[1], 65.535);
        assert_eq!(back.as_raw()[2], f32::INFINITY);
    }

    #[test]
    fn eight_bit_png_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("8.png");
        image::GrayImage::new(2, 2).save(&path).unwrap();
        let err = read_kitti_disparity(&path).unwrap_err().to_string();
        assert!(err.contains("8.png") && err.contains("16-bit"), "{err}");
    }
}
