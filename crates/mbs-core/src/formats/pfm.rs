//! Portable Float Map: `PF` (colour) or `Pf` (grey), `W H`, a scale whose sign
//! gives the byte order (negative = little-endian), then float32 rows stored
//! bottom-to-top. `+inf` marks unknown values (Middlebury convention).

use std::io::Write;
use std::path::Path;

use image::Rgb32FImage;

use crate::FloatImage;
use crate::atomic::write_atomic;
use crate::error::{FormatError, Result};

/// Byte order of the samples in a PFM file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Endian {
    /// Little-endian (scale written as `-1.0`), what x86 tools write.
    Little,
    /// Big-endian (scale written as `1.0`).
    Big,
}

/// The content of a PFM file.
#[derive(Debug, Clone, PartialEq)]
pub enum Pfm {
    /// A `Pf` file: one channel.
    Grey(FloatImage),
    /// A `PF` file: three channels.
    Rgb(Rgb32FImage),
}

/// Reads a PFM file, grey or colour, either byte order.
pub fn read_pfm(path: &Path) -> Result<Pfm> {
    let bytes = crate::regular::read_bytes(path)?;
    decode_pfm(&bytes).map_err(|message| FormatError::invalid(path, message))
}

/// Reads a greyscale PFM file (a depth or disparity map).
pub fn read_pfm_grey(path: &Path) -> Result<FloatImage> {
    match read_pfm(path)? {
        Pfm::Grey(image) => Ok(image),
        Pfm::Rgb(_) => Err(FormatError::invalid(
            path,
            "expected a greyscale PFM (Pf), found colour (PF)",
        )),
    }
}

/// Writes a greyscale PFM atomically in the given byte order.
pub fn write_pfm_grey(path: &Path, image: &FloatImage, endian: Endian) -> Result<()> {
    write_pfm_samples(
        path,
        "Pf",
        image.width(),
        image.height(),
        1,
        image.as_raw(),
        endian,
    )
}

/// Writes a colour PFM atomically in the given byte order.
pub fn write_pfm_rgb(path: &Path, image: &Rgb32FImage, endian: Endian) -> Result<()> {
    write_pfm_samples(
        path,
        "PF",
        image.width(),
        image.height(),
        3,
        image.as_raw(),
        endian,
    )
}

fn write_pfm_samples(
    path: &Path,
    magic: &str,
    width: u32,
    height: u32,
    channels: usize,
    samples: &[f32],
    endian: Endian,
) -> Result<()> {
    let scale = match endian {
        Endian::Little => "-1.0",
        Endian::Big => "1.0",
    };
    let row_len = width as usize * channels;
    let mut body = Vec::with_capacity(samples.len() * 4);
    for row in samples.chunks(row_len.max(1)).rev() {
        for &v in row {
            body.extend_from_slice(&match endian {
                Endian::Little => v.to_le_bytes(),
                Endian::Big => v.to_be_bytes(),
            });
        }
    }
    write_atomic(path, |w| {
        write!(w, "{magic}\n{width} {height}\n{scale}\n")?;
        w.write_all(&body)
    })
}

/// Decodes PFM bytes; the error is a message without the path.
fn decode_pfm(bytes: &[u8]) -> std::result::Result<Pfm, String> {
    let (header, header_end) = parse_header(bytes)?;
    let PfmHeader {
        channels,
        width,
        height,
        little,
    } = header;
    // Exactly one whitespace byte separates the header from the data.
    let data = bytes.get(header_end + 1..).unwrap_or_default();
    let count = crate::limits::checked_samples(width.into(), height.into(), channels as u64, 4)?;
    if data.len() / 4 < count {
        return Err(format!(
            "truncated PFM data: {} bytes for {width}x{height}x{channels} floats, expected {}",
            data.len(),
            count * 4
        ));
    }
    let samples = top_down_samples(&data[..count * 4], width as usize * channels, little);
    // The sizes were checked above, so the buffers have the right length.
    let size_error = || "internal: PFM buffer size".to_string();
    Ok(if channels == 1 {
        Pfm::Grey(FloatImage::from_raw(width, height, samples).ok_or_else(size_error)?)
    } else {
        Pfm::Rgb(Rgb32FImage::from_raw(width, height, samples).ok_or_else(size_error)?)
    })
}

/// What a PFM header says.
struct PfmHeader {
    /// 1 (`Pf`, grey) or 3 (`PF`, RGB).
    channels: usize,
    /// Width in pixels, above 0.
    width: u32,
    /// Height in pixels, above 0.
    height: u32,
    /// Whether the floats are little-endian (a negative scale).
    little: bool,
}

/// The header at the start of `bytes` and the offset of its last token's
/// end.
fn parse_header(bytes: &[u8]) -> std::result::Result<(PfmHeader, usize), String> {
    let mut cursor = 0usize;
    let mut token = || -> std::result::Result<&str, String> {
        while cursor < bytes.len() && bytes[cursor].is_ascii_whitespace() {
            cursor += 1;
        }
        let start = cursor;
        while cursor < bytes.len() && !bytes[cursor].is_ascii_whitespace() {
            cursor += 1;
        }
        if start == cursor {
            return Err("truncated PFM header".to_string());
        }
        std::str::from_utf8(&bytes[start..cursor])
            .map_err(|_| "PFM header is not ASCII".to_string())
    };
    let channels = match token()? {
        "Pf" => 1,
        "PF" => 3,
        other => {
            return Err(format!(
                "not a PFM file (magic {other:?}, expected Pf or PF)"
            ));
        }
    };
    let width = parse_dimension(token()?)?;
    let height = parse_dimension(token()?)?;
    let scale_text = token()?;
    let scale: f32 = scale_text
        .parse()
        .ok()
        .filter(|s: &f32| s.is_finite() && *s != 0.0)
        .ok_or_else(|| format!("bad PFM scale {scale_text:?}"))?;
    let header = PfmHeader {
        channels,
        width,
        height,
        little: scale < 0.0,
    };
    Ok((header, cursor))
}

/// A header's width or height: a positive integer.
fn parse_dimension(s: &str) -> std::result::Result<u32, String> {
    s.parse::<u32>()
        .ok()
        .filter(|v| *v > 0)
        .ok_or_else(|| format!("bad PFM dimension {s:?} (expected a positive integer)"))
}

/// The floats of `data`, rows of `row_len` floats each, reordered from
/// PFM's bottom-up rows to top-down.
fn top_down_samples(data: &[u8], row_len: usize, little: bool) -> Vec<f32> {
    let mut samples = Vec::with_capacity(data.len() / 4);
    for row in data.chunks_exact(row_len * 4).rev() {
        samples.extend(row.chunks_exact(4).map(|b| {
            let b = [b[0], b[1], b[2], b[3]];
            if little {
                f32::from_le_bytes(b)
            } else {
                f32::from_be_bytes(b)
            }
        }));
    }
    samples
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_grey() -> FloatImage {
        FloatImage::from_fn(7, 4, |x, y| {
            image::Luma([if x == 3 && y == 1 {
                f32::INFINITY
            } else {
                x as f32 * 0.5 - y as f32 * 1.25
            }])
        })
    }

    #[test]
    fn grey_round_trip_both_endiannesses_with_inf() {
        let dir = tempfile::tempdir().unwrap();
        let img = sample_grey();
        for endian in [Endian::Little, Endian::Big] {
            let path = dir.path().join(format!("{endian:?}.pfm"));
            write_pfm_grey(&path, &img, endian).unwrap();
            let back = read_pfm_grey(&path).unwrap();
            assert_eq!(back, img);
            assert_eq!(back.get_pixel(3, 1).0[0], f32::INFINITY);
        }
    }

    #[test]
    fn colour_round_trip_both_endiannesses() {
        let dir = tempfile::tempdir().unwrap();
        let img =
            Rgb32FImage::from_fn(3, 5, |x, y| image::Rgb([x as f32, y as f32, f32::INFINITY]));
        for endian in [Endian::Little, Endian::Big] {
            let path = dir.path().join("c.pfm");
            write_pfm_rgb(&path, &img, endian).unwrap();
            assert_eq!(read_pfm(&path).unwrap(), Pfm::Rgb(img.clone()));
        }
    }

    #[test]
    fn rows_are_stored_bottom_to_top_little_endian() {
        let img = FloatImage::from_raw(1, 2, vec![1.0, 2.0]).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("o.pfm");
        write_pfm_grey(&path, &img, Endian::Little).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let header = b"Pf\n1 2\n-1.0\n";
        assert_eq!(&bytes[..header.len()], header);
        assert_eq!(
            &bytes[header.len()..header.len() + 4],
            &2.0f32.to_le_bytes()
        );
    }

    #[test]
    fn truncated_and_foreign_files_are_rejected_with_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.pfm");
        std::fs::write(&path, b"Pf\n4 4\n-1.0\n\0\0\0\0").unwrap();
        let err = read_pfm(&path).unwrap_err().to_string();
        assert!(err.contains("t.pfm") && err.contains("truncated"), "{err}");
        std::fs::write(&path, b"P6\n4 4\n255\n").unwrap();
        assert!(
            read_pfm(&path)
                .unwrap_err()
                .to_string()
                .contains("not a PFM")
        );
    }

    #[test]
    fn absurd_header_sizes_are_refused_before_allocating() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("huge.pfm");
        std::fs::write(&path, b"Pf\n2147483648 2147483648\n-1.0\n\0\0\0\0").unwrap();
        let err = read_pfm(&path).unwrap_err().to_string();
        assert!(err.contains("huge.pfm"), "{err}");
        assert!(err.contains("2147483648x2147483648"), "{err}");
    }
}
