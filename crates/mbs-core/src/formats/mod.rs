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

/// The float formats a depth or disparity map can be written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FloatFormat {
    /// OpenEXR, one float32 channel named `Y`, uncompressed.
    Exr,
    /// Portable float map, greyscale, little-endian.
    Pfm,
}

impl FloatFormat {
    /// The file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            FloatFormat::Exr => "exr",
            FloatFormat::Pfm => "pfm",
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
    match ext.as_str() {
        "pfm" => pfm::read_pfm_grey(path),
        "exr" => exr::read_exr(path),
        "png" => png16::read_kitti_disparity(path),
        _ => Err(crate::FormatError::invalid(
            path,
            "unknown float map extension (expected .pfm, .exr or a KITTI 16-bit .png)",
        )),
    }
}
