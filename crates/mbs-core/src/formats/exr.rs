//! Float EXR maps through the `exr` crate: one float32 channel named `Y`
//! (the name OpenCV and image viewers read as greyscale), uncompressed.

use std::path::Path;

use exr::prelude::*;

use crate::FloatImage;
use crate::atomic::write_atomic;
use crate::error::{FormatError, Result};

/// Channel names accepted when reading, in order of preference.
const CHANNEL_NAMES: [&str; 4] = ["Y", "Z", "R", "depth"];

/// Writes a float map as a single-channel float32 EXR, atomically.
pub fn write_exr(path: &Path, map: &FloatImage) -> Result<()> {
    let size = (map.width() as usize, map.height() as usize);
    let channel = AnyChannel::new("Y", FlatSamples::F32(map.as_raw().clone()));
    let layer = Layer::new(
        size,
        LayerAttributes::default(),
        Encoding::UNCOMPRESSED,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    let image = Image::from_layer(layer);
    write_atomic(path, |w| {
        image
            .write()
            .to_buffered(w)
            .map_err(|e| std::io::Error::other(e.to_string()))
    })
}

/// Reads the first layer of an EXR file: the channel `Y`, `Z`, `R` or
/// `depth`, or the only channel there is, converted to float32.
pub fn read_exr(path: &Path) -> Result<FloatImage> {
    let exr_error = |source| FormatError::Exr {
        path: path.to_path_buf(),
        source,
    };
    // The header's sizes are checked before the pixels are read.
    // Read through a checked handle: a FIFO under the name must not block.
    let bytes = crate::regular::read_bytes(path)?;
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&bytes), false)
        .map_err(exr_error)?;
    for header in &meta.headers {
        let size = header.layer_size;
        crate::limits::checked_samples(
            size.width() as u64,
            size.height() as u64,
            header.channels.list.len() as u64,
            4,
        )
        .map_err(|message| FormatError::invalid(path, message))?;
    }
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(exr_error)?;
    let layer = &image.layer_data;
    let channels = &layer.channel_data.list;
    let chosen = CHANNEL_NAMES
        .iter()
        .find_map(|name| channels.iter().find(|c| c.name.eq(name)))
        .or_else(|| (channels.len() == 1).then(|| &channels[0]))
        .ok_or_else(|| {
            let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
            FormatError::invalid(
                path,
                format!("no depth channel (Y, Z, R or depth) among {names:?}"),
            )
        })?;
    let data: Vec<f32> = chosen.sample_data.values_as_f32().collect();
    let (width, height) = (layer.size.width() as u32, layer.size.height() as u32);
    FloatImage::from_raw(width, height, data)
        .ok_or_else(|| FormatError::invalid(path, "channel size does not match the layer size"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_values_and_inf() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.exr");
        let map = FloatImage::from_fn(9, 5, |x, y| {
            image::Luma([if x == y {
                f32::INFINITY
            } else {
                x as f32 * 1.5 + y as f32 / 3.0
            }])
        });
        write_exr(&path, &map).unwrap();
        assert_eq!(read_exr(&path).unwrap(), map);
    }

    #[test]
    fn garbage_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.exr");
        std::fs::write(&path, b"not an exr").unwrap();
        let err = read_exr(&path).unwrap_err().to_string();
        assert!(err.contains("bad.exr"), "{err}");
    }
}
