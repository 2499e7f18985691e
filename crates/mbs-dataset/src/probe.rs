//! Cheap checks of image files: size and pixel type from the header, plus a
//! truncation check (PNG `IEND` trailer, raw-data length for PNM), or a full
//! decode in deep mode. Fast enough for 100k+ files.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use image::{ColorType, ImageDecoder, ImageFormat, ImageReader};

/// What a probed file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelType {
    /// A raster image with this colour type.
    Raster(ColorType),
    /// A float map (PFM or EXR).
    Float,
}

/// The size and pixel type of an image file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageInfo {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The pixel type.
    pub pixels: PixelType,
}

/// Why a file failed the probe.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ProbeError {
    /// The file does not exist.
    #[error("missing file")]
    Missing,
    /// The file ends before its data does.
    #[error("truncated file: {0}")]
    Truncated(String),
    /// The file cannot be decoded.
    #[error("cannot decode: {0}")]
    Corrupt(String),
}

/// The PNG end-of-image chunk: length 0, type `IEND`, CRC.
const PNG_IEND: [u8; 12] = [0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xAE, 0x42, 0x60, 0x82];

/// Probes `path`. Fast mode reads the header and checks that the file is not
/// truncated; `deep` decodes every pixel (and checks CRCs). The file is
/// opened once, without blocking, and its type checked on the open handle
/// ([`mbs_core::regular`]): a folder, a FIFO or another special file is
/// refused at once, saying what it is, even one swapped in after a check.
pub fn probe(path: &Path, deep: bool) -> Result<ImageInfo, ProbeError> {
    let file = open(path)?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        "pfm" | "exr" => probe_float(path, file, deep),
        _ => probe_raster(path, file, deep),
    }
}

/// `path` opened as [`mbs_core::regular::open_regular`] does; nothing
/// there is [`ProbeError::Missing`], anything else that cannot be opened
/// (a folder, a FIFO, no permission) is [`ProbeError::Corrupt`] saying why.
fn open(path: &Path) -> Result<File, ProbeError> {
    mbs_core::regular::open_regular(path).map_err(|e| match e {
        mbs_core::FormatError::Io { source, .. }
            if source.kind() == std::io::ErrorKind::NotFound =>
        {
            ProbeError::Missing
        }
        e => ProbeError::Corrupt(e.reason()),
    })
}

fn probe_raster(path: &Path, file: File, deep: bool) -> Result<ImageInfo, ProbeError> {
    let corrupt = |e: &dyn std::fmt::Display| ProbeError::Corrupt(e.to_string());
    // A second handle on the same open file, for the checks after the header.
    let mut tail_file = file.try_clone().map_err(|e| corrupt(&e))?;
    let mut reader = ImageReader::new(BufReader::new(file));
    if deep {
        // As `image::open`: the format the extension names.
        reader.set_format(ImageFormat::from_path(path).map_err(|e| classify_decode_error(&e))?);
        let image = reader.decode().map_err(|e| classify_decode_error(&e))?;
        return Ok(ImageInfo {
            width: image.width(),
            height: image.height(),
            pixels: PixelType::Raster(image.color()),
        });
    }
    if let Ok(format) = ImageFormat::from_path(path) {
        reader.set_format(format);
    }
    let reader = reader.with_guessed_format().map_err(|e| corrupt(&e))?;
    let format = reader.format();
    let decoder = reader
        .into_decoder()
        .map_err(|e| classify_decode_error(&e))?;
    let (width, height) = decoder.dimensions();
    let (pixels, total_bytes) = (decoder.color_type(), decoder.total_bytes());
    drop(decoder);
    let info = ImageInfo {
        width,
        height,
        pixels: PixelType::Raster(pixels),
    };
    let file_len = tail_file.metadata().map_err(|e| corrupt(&e))?.len();
    match format {
        Some(ImageFormat::Png) => {
            let mut tail = [0u8; 12];
            tail_file
                .seek(SeekFrom::End(-12))
                .and_then(|_| tail_file.read_exact(&mut tail))
                .map_err(|e| corrupt(&e))?;
            if tail != PNG_IEND {
                return Err(ProbeError::Truncated(
                    "PNG does not end with an IEND chunk".into(),
                ));
            }
        }
        Some(ImageFormat::Pnm) => {
            let needed = pnm_header_len(&mut tail_file).map_err(|e| corrupt(&e))? + total_bytes;
            if file_len < needed {
                return Err(ProbeError::Truncated(format!(
                    "{file_len} bytes, the header and pixel data need {needed}"
                )));
            }
        }
        _ => {}
    }
    Ok(info)
}

/// The length of a binary PNM header: for P5/P6, magic, width, height and
/// maxval tokens (with `#` comments between them), then one whitespace byte;
/// for PAM (P7), everything up to the `ENDHDR` line.
fn pnm_header_len(file: &mut File) -> std::io::Result<u64> {
    let mut head = Vec::with_capacity(512);
    file.seek(SeekFrom::Start(0))?;
    file.by_ref().take(512).read_to_end(&mut head)?;
    if head.starts_with(b"P7") {
        const END: &[u8] = b"ENDHDR\n";
        return head
            .windows(END.len())
            .position(|w| w == END)
            .map(|p| (p + END.len()) as u64)
            .ok_or_else(|| std::io::Error::other("PAM header without ENDHDR"));
    }
    let mut pos = 0;
    for _ in 0..4 {
        loop {
            match head.get(pos) {
                Some(b'#') => {
                    while head.get(pos).is_some_and(|b| *b != b'\n') {
                        pos += 1;
                    }
                }
                Some(b) if b.is_ascii_whitespace() => pos += 1,
                Some(_) => break,
                None => return Err(std::io::Error::other("PNM header longer than 512 bytes")),
            }
        }
        while head.get(pos).is_some_and(|b| !b.is_ascii_whitespace()) {
            pos += 1;
        }
    }
    Ok(pos as u64 + 1)
}

fn classify_decode_error(e: &image::ImageError) -> ProbeError {
    let text = e.to_string();
    let io_eof = matches!(e, image::ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof);
    if io_eof
        || text.contains("end of file")
        || text.contains("EOF")
        || text.contains("unexpected end")
    {
        ProbeError::Truncated(text)
    } else {
        ProbeError::Corrupt(text)
    }
}

fn probe_float(path: &Path, file: File, deep: bool) -> Result<ImageInfo, ProbeError> {
    let is_exr = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    let (width, height) = if deep || !is_exr {
        // PFM has no cheaper path than reading it: the header says nothing of truncation.
        // (It opens the file again, as checked a handle as `file`.)
        drop(file);
        let map = mbs_core::formats::read_float_map(path).map_err(|e| classify_format_error(&e))?;
        map.dimensions()
    } else {
        let meta = exr::meta::MetaData::read_from_buffered(BufReader::new(file), false)
            .map_err(|e| ProbeError::Corrupt(e.to_string()))?;
        let header = meta
            .headers
            .first()
            .ok_or_else(|| ProbeError::Corrupt("EXR file has no layer".into()))?;
        (
            header.layer_size.width() as u32,
            header.layer_size.height() as u32,
        )
    };
    Ok(ImageInfo {
        width,
        height,
        pixels: PixelType::Float,
    })
}

fn classify_format_error(e: &mbs_core::FormatError) -> ProbeError {
    let text = e.to_string();
    if text.contains("truncated") {
        ProbeError::Truncated(text)
    } else {
        ProbeError::Corrupt(text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_png(path: &Path, w: u32, h: u32) {
        image::RgbImage::from_fn(w, h, |x, y| {
            image::Rgb([(x * 7) as u8, (y * 13) as u8, (x ^ y) as u8])
        })
        .save(path)
        .unwrap();
    }

    #[test]
    fn reads_size_and_type_from_the_header() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        write_png(&path, 40, 30);
        for deep in [false, true] {
            let info = probe(&path, deep).unwrap();
            assert_eq!((info.width, info.height), (40, 30));
            assert_eq!(info.pixels, PixelType::Raster(ColorType::Rgb8));
        }
    }

    #[test]
    fn truncated_png_is_caught_in_fast_and_deep_mode() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.png");
        write_png(&path, 64, 64);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        assert!(matches!(probe(&path, false), Err(ProbeError::Truncated(_))));
        assert!(matches!(
            probe(&path, true),
            Err(ProbeError::Truncated(_) | ProbeError::Corrupt(_))
        ));
    }

    #[test]
    fn truncated_ppm_and_missing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.ppm");
        write_png(&dir.path().join("x.png"), 8, 8);
        image::open(dir.path().join("x.png"))
            .unwrap()
            .save(&path)
            .unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(probe(&path, false).is_ok());
        std::fs::write(&path, &bytes[..bytes.len() - 10]).unwrap();
        assert!(matches!(probe(&path, false), Err(ProbeError::Truncated(_))));
        // A P6 file with a comment in its header, as Middlebury ships them.
        let p6 = dir.path().join("p6.ppm");
        let mut data = b"P6\n# made by hand\n2 1\n255\n".to_vec();
        data.extend_from_slice(&[1, 2, 3, 4, 5, 6]);
        std::fs::write(&p6, &data).unwrap();
        assert_eq!(probe(&p6, false).unwrap().width, 2);
        std::fs::write(&p6, &data[..data.len() - 1]).unwrap();
        assert!(matches!(probe(&p6, false), Err(ProbeError::Truncated(_))));
        assert_eq!(
            probe(&dir.path().join("none.png"), false),
            Err(ProbeError::Missing)
        );
        let folder = dir.path().join("folder.png");
        std::fs::create_dir(&folder).unwrap();
        assert_eq!(
            probe(&folder, false),
            Err(ProbeError::Corrupt(
                "is a folder, not a regular file".into()
            ))
        );
    }

    #[test]
    fn float_maps_are_probed() {
        let dir = tempfile::tempdir().unwrap();
        let map = mbs_core::FloatImage::new(5, 4);
        let pfm = dir.path().join("d.pfm");
        let exr = dir.path().join("d.exr");
        mbs_core::formats::pfm::write_pfm_grey(&pfm, &map, mbs_core::formats::pfm::Endian::Little)
            .unwrap();
        mbs_core::formats::exr::write_exr(&exr, &map).unwrap();
        for path in [&pfm, &exr] {
            let info = probe(path, false).unwrap();
            assert_eq!(
                (info.width, info.height, info.pixels),
                (5, 4, PixelType::Float)
            );
        }
    }

    /// A FIFO, a socket, a device or a folder named like an image (PNG,
    /// EXR, PFM) is refused at once in fast and deep mode, saying what it
    /// is: the reader opens it without blocking and checks the open handle
    /// (a FIFO given to a plain open blocks until a writer comes).
    #[cfg(unix)]
    #[test]
    fn special_files_are_refused_without_blocking() {
        use mbs_test_support::special::special_files;
        for extension in ["png", "exr", "pfm"] {
            let dir = tempfile::tempdir().unwrap();
            for special in special_files(dir.path(), extension) {
                for deep in [false, true] {
                    let path = special.path.clone();
                    let (done, outcome) = std::sync::mpsc::channel();
                    std::thread::spawn(move || done.send(probe(&path, deep)));
                    let result = outcome
                        .recv_timeout(std::time::Duration::from_secs(10))
                        .unwrap_or_else(|_| panic!("probing {} blocked", special.path.display()));
                    let expected = format!("is {}", special.kind);
                    assert!(
                        matches!(&result, Err(ProbeError::Corrupt(m)) if m.contains(&expected)
                            && m.contains("not a regular file")),
                        "{}: {result:?}",
                        special.path.display()
                    );
                }
            }
        }
    }
}
