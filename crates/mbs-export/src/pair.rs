//! The pair an export is checked on: a built-in real one (Middlebury's
//! Teddy, quarter size) or the user's, fitted to the export's size.

use image::imageops::{FilterType, resize};
use mbs_core::RgbImage;

/// Middlebury 2003 Teddy, left view (`im2.png`, 450x375; D. Scharstein and
/// R. Szeliski, CVPR 2003; testdata/README.md).
const TEDDY_LEFT: &[u8] = include_bytes!("../../../testdata/middlebury-teddy/im2.png");
/// Its right view (`im6.png`).
const TEDDY_RIGHT: &[u8] = include_bytes!("../../../testdata/middlebury-teddy/im6.png");

/// The built-in check pair.
pub fn built_in() -> (RgbImage, RgbImage) {
    let decode = |bytes: &[u8]| {
        image::load_from_memory(bytes)
            .expect("the built-in pair is a valid PNG")
            .to_rgb8()
    };
    (decode(TEDDY_LEFT), decode(TEDDY_RIGHT))
}

/// `image` resized to `width` x `height` (bilinear, as ONNX stereo models
/// are fed), unchanged when it has that size.
pub fn fit(image: &RgbImage, width: u32, height: u32) -> RgbImage {
    if image.dimensions() == (width, height) {
        return image.clone();
    }
    resize(image, width, height, FilterType::Triangle)
}

/// The smallest side an export takes, pixels.
pub const MIN_SIDE: usize = 32;
/// The largest.
pub const MAX_SIDE: usize = 4096;

/// Refuses a `height` x `width` outside [`MIN_SIDE`, `MAX_SIDE`], naming
/// the nearest size that is inside.
pub fn check_size(height: usize, width: usize) -> Result<(), String> {
    let clamp = |side: usize| side.clamp(MIN_SIDE, MAX_SIDE);
    if clamp(height) == height && clamp(width) == width {
        return Ok(());
    }
    Err(format!(
        "{height}x{width} cannot be exported: each side must be {MIN_SIDE} to {MAX_SIDE} \
         pixels; the nearest size is {}x{}",
        clamp(height),
        clamp(width)
    ))
}
