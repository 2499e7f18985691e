//! File formats: 8-bit RGB (PNG/PPM), KITTI 16-bit disparity PNG, 16-bit
//! millimetre depth PNG, PFM, float EXR and CARLA RGB-encoded depth.
//!
//! Readers and writers take a path and return a [`crate::FormatError`] that
//! names it. Writers are atomic (see [`crate::atomic`]).

pub mod carla;
pub mod exr;
pub mod pfm;
pub mod png16;
pub mod rgb;

/// The PNG encoder every writer uses: fast deflate (several times faster
/// than the default level, files somewhat larger) with adaptive filtering.
pub fn png_encoder<W: std::io::Write>(writer: W) -> image::codecs::png::PngEncoder<W> {
    image::codecs::png::PngEncoder::new_with_quality(
        writer,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Adaptive,
    )
}

/// Decodes a raster image (PNG, PNM) whatever its extension says, within
/// [`crate::limits`]; a folder, a FIFO or another special file, a missing
/// file or an undecodable one is an error naming the path.
pub fn open_image(path: &std::path::Path) -> crate::Result<image::DynamicImage> {
    let file = crate::regular::open_regular(path)?;
    let mut reader = image::ImageReader::new(std::io::BufReader::new(file))
        .with_guessed_format()
        .map_err(|e| crate::FormatError::io(path, e))?;
    if reader.format().is_none() {
        return Err(crate::FormatError::invalid(
            path,
            "not an image this tool reads (expected PNG or PNM)",
        ));
    }
    reader.limits(crate::limits::image_limits());
    reader
        .decode()
        .map_err(|e| crate::FormatError::image(path, e))
}

/// The file formats a disparity map is written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum DisparityFormat {
    /// PFM float32, +inf = invalid.
    Pfm,
    /// KITTI 16-bit PNG, value / 256 px, 0 = invalid.
    Png16,
}

impl DisparityFormat {
    /// The file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            DisparityFormat::Pfm => "pfm",
            DisparityFormat::Png16 => "png",
        }
    }

    /// Writes `disparity` to `path` in this format, atomically.
    pub fn write(self, path: &std::path::Path, disparity: &crate::FloatImage) -> crate::Result<()> {
        match self {
            DisparityFormat::Pfm => pfm::write_pfm_grey(path, disparity, pfm::Endian::Little),
            DisparityFormat::Png16 => png16::write_kitti_disparity(path, disparity),
        }
    }
}

/// The file formats a metric depth map is written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum DepthFormat {
    /// OpenEXR float32, one channel `Y`, metres.
    Exr,
    /// PFM float32, metres.
    Pfm,
    /// 16-bit PNG in millimetres (at most 65.535 m).
    Png16,
}

impl DepthFormat {
    /// Writes `depth` (metres, `+inf` = invalid) to `path` in this format,
    /// atomically.
    pub fn write(self, path: &std::path::Path, depth: &crate::FloatImage) -> crate::Result<()> {
        match self {
            DepthFormat::Exr => exr::write_exr(path, depth),
            DepthFormat::Pfm => pfm::write_pfm_grey(path, depth, pfm::Endian::Little),
            DepthFormat::Png16 => png16::write_depth_mm(path, depth),
        }
    }
}

/// Reads a float map (depth or disparity) from a `.pfm`, `.exr` file, or a
/// KITTI 16-bit disparity `.png` (value / 256, 0 = invalid), chosen by
/// extension. Invalid pixels come back as `+inf`.
pub fn read_float_map(path: &std::path::Path) -> crate::Result<crate::FloatImage> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if path.is_dir() {
        return Err(crate::FormatError::invalid(
            path,
            "is a folder, expected a float map file",
        ));
    }
    match ext.as_str() {
        "pfm" => pfm::read_pfm_grey(path),
        "exr" => exr::read_exr(path),
        "png" => png16::read_kitti_disparity(path),
        _ => Err(crate::FormatError::invalid(
            path,
            format!(
                "unknown float map extension {:?} (expected .pfm, .exr or a KITTI 16-bit .png)",
                path.extension().unwrap_or_default()
            ),
        )),
    }
}

/// Reads a disparity map whatever its encoding: `.pfm` / `.exr` floats
/// (`+inf` or NaN = invalid), or a `.png` / `.pgm` of integer codes `v` meaning
/// `v / png_scale` pixels with `0` = invalid. `png_scale` defaults to 256
/// (KITTI) for 16-bit PNGs and to 1 for 8-bit ones (Middlebury 2001/2003
/// ground truth needs its own factor, e.g. 4 for quarter-size Teddy, 16
/// for Tsukuba). Invalid pixels come back as `+inf`.
pub fn read_disparity(
    path: &std::path::Path,
    png_scale: Option<f32>,
) -> crate::Result<crate::FloatImage> {
    let is_integer = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png") || e.eq_ignore_ascii_case("pgm"));
    if !is_integer {
        let mut map = read_float_map(path)?;
        map.iter_mut()
            .filter(|v| v.is_nan())
            .for_each(|v| *v = f32::INFINITY);
        return Ok(map);
    }
    let image = open_image(path)?;
    let codes = match image {
        image::DynamicImage::ImageLuma16(codes) => {
            return Ok(png16::decode_scaled(
                &codes,
                png_scale.unwrap_or(png16::KITTI_DISPARITY_SCALE),
            ));
        }
        image::DynamicImage::ImageLuma8(codes) => codes,
        other => {
            return Err(crate::FormatError::invalid(
                path,
                format!(
                    "expected a greyscale disparity PNG, found {:?}",
                    other.color()
                ),
            ));
        }
    };
    Ok(png16::decode_scaled(&codes, png_scale.unwrap_or(1.0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn read_disparity_decodes_every_encoding() {
        let dir = tempfile::tempdir().unwrap();
        // 8-bit Middlebury-style PNG: value / scale, 0 = unknown.
        let eight = dir.path().join("gt8.png");
        image::GrayImage::from_raw(3, 1, vec![0, 4, 255])
            .unwrap()
            .save(&eight)
            .unwrap();
        let d = read_disparity(&eight, Some(4.0)).unwrap();
        assert_eq!(d.as_raw(), &vec![f32::INFINITY, 1.0, 63.75]);
        assert_eq!(read_disparity(&eight, None).unwrap().as_raw()[1], 4.0);
        // 16-bit KITTI PNG: value / 256 by default.
        let sixteen = dir.path().join("gt16.png");
        let codes = png16::Gray16Image::from_raw(2, 1, vec![0, 512]).unwrap();
        png16::write_gray16(&sixteen, &codes).unwrap();
        assert_eq!(
            read_disparity(&sixteen, None).unwrap().as_raw(),
            &vec![f32::INFINITY, 2.0]
        );
        // PFM: NaN becomes +inf.
        let float = dir.path().join("d.pfm");
        let map = crate::FloatImage::from_raw(2, 1, vec![f32::NAN, 1.5]).unwrap();
        pfm::write_pfm_grey(&float, &map, pfm::Endian::Little).unwrap();
        assert_eq!(
            read_disparity(&float, None).unwrap().as_raw(),
            &vec![f32::INFINITY, 1.5]
        );
        // 8-bit PGM (Middlebury 2001 ground truth) decodes like 8-bit PNG.
        let pgm = dir.path().join("gt.pgm");
        image::GrayImage::from_raw(2, 1, vec![0, 32])
            .unwrap()
            .save(&pgm)
            .unwrap();
        assert_eq!(
            read_disparity(&pgm, Some(16.0)).unwrap().as_raw(),
            &vec![f32::INFINITY, 2.0]
        );
        // Colour PNGs are refused with the file's name.
        let colour = dir.path().join("c.png");
        image::RgbImage::new(1, 1).save(&colour).unwrap();
        let err = read_disparity(&colour, None).unwrap_err();
        assert!(err.to_string().contains("c.png"), "{err}");
    }
}
