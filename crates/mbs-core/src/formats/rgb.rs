//! 8-bit RGB views (PNG, PPM and anything else the `image` crate decodes).

use std::path::Path;

use image::ImageEncoder;

use crate::atomic::write_atomic;
use crate::error::{FormatError, Result};
use crate::{MaskImage, RgbImage};

/// Reads an image file as 8-bit RGB. Greyscale or 16-bit files are converted;
/// use [`read_rgb8_strict`] to refuse them.
pub fn read_rgb(path: &Path) -> Result<RgbImage> {
    let image = super::open_image(path)?;
    Ok(image.into_rgb8())
}

/// Reads an image file that must be 8-bit RGB (no alpha, no 16-bit, no grey):
/// the encoding CARLA uses for depth.
pub fn read_rgb8_strict(path: &Path) -> Result<RgbImage> {
    let image = super::open_image(path)?;
    match image {
        image::DynamicImage::ImageRgb8(rgb) => Ok(rgb),
        other => Err(FormatError::invalid(
            path,
            format!("expected 8-bit RGB, found {:?}", other.color()),
        )),
    }
}

/// Reads a photo that must be 8-bit colour (RGB, or RGBA with the alpha
/// ignored): the reference view of a set made from one image, which is kept
/// as it is. A grey or 16-bit (or float) image is an error naming the file
/// and saying what to do, since a set's views are 8-bit colour.
pub fn read_colour_photo(path: &Path) -> Result<RgbImage> {
    use image::ColorType;
    let image = super::open_image(path)?;
    let colour = image.color();
    let problem = match colour {
        ColorType::Rgb8 | ColorType::Rgba8 => return Ok(image.into_rgb8()),
        ColorType::L8 | ColorType::La8 => {
            "a grey image; a set's views are colour: convert it to 8-bit RGB first".to_string()
        }
        other => format!(
            "{other:?} ({} bits a channel); a set's views are 8-bit colour: convert it to 8-bit RGB first",
            other.bits_per_pixel() / u16::from(other.channel_count())
        ),
    };
    Err(FormatError::invalid(path, problem))
}

/// Encodes `image` as an 8-bit RGB PNG into `writer`.
fn encode_rgb<W: std::io::Write>(writer: W, image: &RgbImage) -> std::io::Result<()> {
    super::png_encoder(writer)
        .write_image(
            image.as_raw(),
            image.width(),
            image.height(),
            image::ExtendedColorType::Rgb8,
        )
        .map_err(std::io::Error::other)
}

/// Writes an 8-bit RGB PNG atomically.
pub fn write_rgb_png(path: &Path, image: &RgbImage) -> Result<()> {
    write_atomic(path, |w| encode_rgb(w, image))
}

/// `image` as the bytes of an 8-bit RGB PNG, the same bytes
/// [`write_rgb_png`] writes.
pub fn rgb_png_bytes(image: &RgbImage) -> std::io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    encode_rgb(&mut bytes, image)?;
    Ok(bytes)
}

/// Writes an 8-bit single-channel PNG (a mask) atomically.
pub fn write_mask_png(path: &Path, mask: &MaskImage) -> Result<()> {
    write_atomic(path, |w| {
        super::png_encoder(w)
            .write_image(
                mask.as_raw(),
                mask.width(),
                mask.height(),
                image::ExtendedColorType::L8,
            )
            .map_err(std::io::Error::other)
    })
}

/// Reads an 8-bit single-channel PNG mask.
pub fn read_mask(path: &Path) -> Result<MaskImage> {
    let image = super::open_image(path)?;
    match image {
        image::DynamicImage::ImageLuma8(mask) => Ok(mask),
        other => Err(FormatError::invalid(
            path,
            format!(
                "expected an 8-bit greyscale mask, found {:?}",
                other.color()
            ),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn photos_must_be_8_bit_colour() {
        let dir = tempfile::tempdir().unwrap();
        let rgba = dir.path().join("rgba.png");
        image::RgbaImage::from_pixel(3, 2, image::Rgba([1, 2, 3, 0]))
            .save(&rgba)
            .unwrap();
        let read = read_colour_photo(&rgba).unwrap();
        assert_eq!(read, RgbImage::from_pixel(3, 2, image::Rgb([1, 2, 3])));
        let grey = dir.path().join("grey.png");
        write_mask_png(&grey, &MaskImage::new(2, 2)).unwrap();
        let err = read_colour_photo(&grey).unwrap_err().to_string();
        assert!(
            err.contains("grey.png") && err.contains("a grey image"),
            "{err}"
        );
        let deep = dir.path().join("deep.png");
        image::ImageBuffer::<image::Rgb<u16>, _>::from_pixel(2, 2, image::Rgb([9u16, 9, 9]))
            .save(&deep)
            .unwrap();
        let err = read_colour_photo(&deep).unwrap_err().to_string();
        assert!(
            err.contains("deep.png") && err.contains("Rgb16 (16 bits a channel)"),
            "{err}"
        );
    }

    #[test]
    fn rgb_png_round_trip_and_strict_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let img = RgbImage::from_fn(5, 3, |x, y| image::Rgb([x as u8, y as u8, 7]));
        write_rgb_png(&path, &img).unwrap();
        assert_eq!(read_rgb8_strict(&path).unwrap(), img);

        let grey = dir.path().join("g.png");
        write_mask_png(&grey, &MaskImage::new(2, 2)).unwrap();
        let err = read_rgb8_strict(&grey).unwrap_err().to_string();
        assert!(
            err.contains("g.png") && err.contains("expected 8-bit RGB"),
            "{err}"
        );
        assert_eq!(read_mask(&grey).unwrap().dimensions(), (2, 2));
    }

    #[test]
    fn reads_real_middlebury_ppm() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../testdata/middlebury-tsukuba-row3/scene1.row3.col1.ppm");
        let img = read_rgb(&path).unwrap();
        assert_eq!(img.dimensions(), (384, 288));
    }

    #[test]
    fn missing_file_error_names_it() {
        let err = read_rgb(Path::new("/no/such/view.png"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("/no/such/view.png"), "{err}");
    }
}
