//! Upper bounds on sizes read from files and flags. A header or a flag that
//! claims more is refused with a message, before anything is allocated, and
//! every size is computed with checked arithmetic.

/// The longest image side mbs accepts (pixels).
pub const MAX_IMAGE_SIDE: u32 = 1 << 15;

/// The most pixels an image may have (2^28: 1 GiB as one float channel).
pub const MAX_IMAGE_PIXELS: u64 = 1 << 28;

/// The most bytes one decoded image may take in memory.
pub const MAX_IMAGE_BYTES: u64 = 4 << 30;

/// The most cameras a rig may have.
pub const MAX_VIEWS: usize = 64;

/// The most worker threads a command starts.
pub const MAX_JOBS: usize = 1024;

/// Checks a `width x height` image of `channels` samples of
/// `bytes_per_sample` bytes against the limits above; returns the number of
/// samples, or a message naming the size and the limit it breaks.
pub fn checked_samples(
    width: u64,
    height: u64,
    channels: u64,
    bytes_per_sample: u64,
) -> Result<usize, String> {
    if width == 0 || height == 0 {
        return Err(format!("empty image size {width}x{height}"));
    }
    let side = u64::from(MAX_IMAGE_SIDE);
    if width > side || height > side {
        return Err(format!(
            "image size {width}x{height} is beyond the limit of {side} pixels a side"
        ));
    }
    let pixels = width * height; // both <= 2^15: no overflow
    if pixels > MAX_IMAGE_PIXELS {
        return Err(format!(
            "image size {width}x{height} is beyond the limit of {MAX_IMAGE_PIXELS} pixels"
        ));
    }
    let samples = pixels
        .checked_mul(channels)
        .filter(|s| s.saturating_mul(bytes_per_sample) <= MAX_IMAGE_BYTES)
        .ok_or_else(|| {
            format!(
                "image size {width}x{height}x{channels} is beyond the limit of {MAX_IMAGE_BYTES} bytes"
            )
        })?;
    usize::try_from(samples).map_err(|_| format!("image size {width}x{height} is too large"))
}

/// The decoding limits of the `image` crate matching the limits above.
pub fn image_limits() -> image::Limits {
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(MAX_IMAGE_BYTES);
    limits
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_within_the_limits_pass() {
        assert_eq!(checked_samples(1242, 375, 3, 1), Ok(1242 * 375 * 3));
        assert_eq!(checked_samples(1, 1, 1, 4), Ok(1));
    }

    #[test]
    fn absurd_sizes_are_refused_with_the_size_in_words() {
        let err = checked_samples(2_147_483_648, 2_147_483_648, 1, 4).unwrap_err();
        assert!(err.contains("2147483648x2147483648"), "{err}");
        assert!(err.contains("32768 pixels a side"), "{err}");
        assert!(checked_samples(0, 5, 1, 4).unwrap_err().contains("empty"));
        let err = checked_samples(32768, 32768, 1, 4).unwrap_err();
        assert!(err.contains("268435456 pixels"), "{err}");
        let err = checked_samples(16384, 16384, 8, 4).unwrap_err();
        assert!(err.contains("bytes"), "{err}");
    }
}
