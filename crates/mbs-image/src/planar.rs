//! Views as the planar float buffers networks read: a crop window of an
//! RGB image as `[3, H, W]` values in `[0, 1]`.

use mbs_core::RgbImage;

/// A crop window, in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    /// First row.
    pub top: usize,
    /// First column.
    pub left: usize,
    /// Rows.
    pub height: usize,
    /// Columns.
    pub width: usize,
}

impl Window {
    /// The whole of `image`.
    pub fn whole(image: &RgbImage) -> Self {
        Window {
            top: 0,
            left: 0,
            height: image.height() as usize,
            width: image.width() as usize,
        }
    }
}

/// Appends `window` of `image` to `out` as planar RGB in `[0, 1]`: the
/// red rows, then the green, then the blue.
///
/// # Panics
/// When `window` does not lie inside `image`.
pub fn append_chw(window: &Window, image: &RgbImage, out: &mut Vec<f32>) {
    let stride = image.width() as usize * 3;
    let raw = image.as_raw();
    for channel in 0..3 {
        for y in window.top..window.top + window.height {
            let row = &raw[y * stride..(y + 1) * stride];
            out.extend(
                (window.left..window.left + window.width)
                    .map(|x| row[x * 3 + channel] as f32 / 255.0),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_becomes_channel_planes_of_rows() {
        // 3x2 image whose red is 10 x + y, green 100 and blue 255.
        let image = RgbImage::from_fn(3, 2, |x, y| image::Rgb([(10 * x + y) as u8, 100, 255]));
        let mut out = Vec::new();
        let window = Window {
            top: 1,
            left: 1,
            height: 1,
            width: 2,
        };
        append_chw(&window, &image, &mut out);
        let expected = [11.0, 21.0, 100.0, 100.0, 255.0, 255.0].map(|v| v / 255.0);
        assert_eq!(out, expected);
        assert_eq!(Window::whole(&image).width, 3);
    }
}
