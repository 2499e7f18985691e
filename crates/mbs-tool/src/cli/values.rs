//! Parsers of flag values with their allowed ranges, so that a bad value is
//! a usage error naming the flag, the value and what is allowed, before any
//! work starts.

use mbs_core::limits::{MAX_IMAGE_SIDE, MAX_JOBS, MAX_VIEWS};
use mbs_eval::Protocol;
use mbs_nets::BackboneKind;
use mbs_nets::device::DeviceList;
use mbs_train::precision::Precision;

/// A finite number above zero (focal lengths, baselines, depths, scales).
pub fn positive(text: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && *v > 0.0)
        .ok_or_else(|| format!("{text:?} is not a finite number above 0"))
}

/// [`positive`] as `f32`.
pub fn positive_f32(text: &str) -> Result<f32, String> {
    positive(text).map(|v| v as f32).and_then(|v| {
        (v.is_finite() && v > 0.0)
            .then_some(v)
            .ok_or_else(|| format!("{text:?} is out of range"))
    })
}

/// An integer in `min..=max`.
fn bounded(text: &str, min: u64, max: u64) -> Result<u64, String> {
    text.trim()
        .parse::<u64>()
        .ok()
        .filter(|v| (min..=max).contains(v))
        .ok_or_else(|| format!("{text:?} is not an integer from {min} to {max}"))
}

/// Disparities the built-in matcher searches: 0 (estimate per pair) up to
/// [`mbs_infer::sgm::MAX_DISPARITY`].
pub fn sgm_disparities(text: &str) -> Result<u32, String> {
    bounded(text, 0, u64::from(mbs_infer::sgm::MAX_DISPARITY)).map(|v| v as u32)
}

/// A device name some network can run on (see
/// [`mbs_nets::device::DeviceName`]), parsed before any work starts.
pub fn device(text: &str) -> Result<mbs_nets::device::DeviceName, String> {
    text.trim()
        .parse()
        .map_err(|e: mbs_nets::NetError| e.to_string())
}

/// A network, as [`BackboneKind`] spells it.
pub fn backbone(text: &str) -> Result<BackboneKind, String> {
    text.parse().map_err(|e: mbs_nets::NetError| e.to_string())
}

/// A training precision, as [`Precision`] spells it.
pub fn precision(text: &str) -> Result<Precision, String> {
    text.parse()
        .map_err(|e: mbs_train::TrainError| e.to_string())
}

/// A comma-separated list of [`device`] names (data-parallel training),
/// parsed once.
pub fn devices(text: &str) -> Result<DeviceList, String> {
    text.parse().map_err(|e: mbs_nets::NetError| e.to_string())
}

/// Worker threads: 0 (one per core) up to [`MAX_JOBS`].
pub fn jobs(text: &str) -> Result<usize, String> {
    bounded(text, 0, MAX_JOBS as u64).map(|v| v as usize)
}

/// Cameras of a rig: 2 up to [`MAX_VIEWS`].
pub fn views(text: &str) -> Result<usize, String> {
    bounded(text, 2, MAX_VIEWS as u64).map(|v| v as usize)
}

/// An image side in pixels: 1 up to [`MAX_IMAGE_SIDE`].
pub fn image_side(text: &str) -> Result<u32, String> {
    bounded(text, 1, MAX_IMAGE_SIDE.into()).map(|v| v as u32)
}

/// Samples per pixel along each axis: 1 up to 8.
pub fn supersample(text: &str) -> Result<u32, String> {
    bounded(text, 1, 8).map(|v| v as u32)
}

/// A count of items to make: 1 up to a million.
pub fn count(text: &str) -> Result<usize, String> {
    bounded(text, 1, 1_000_000).map(|v| v as usize)
}

/// A folder name made from a flag (a town): one confined segment.
pub fn folder_name(text: &str) -> Result<String, String> {
    mbs_core::confine::check_name(text)
        .and_then(|()| {
            (!text.contains('/'))
                .then_some(())
                .ok_or_else(|| "holds a '/'".to_string())
        })
        .map(|()| text.to_string())
        .map_err(|why| format!("{text:?} is not a folder name: it {why}"))
}

/// A `HEIGHTxWIDTH` size such as `256x512`.
pub fn size(text: &str) -> Result<(usize, usize), String> {
    let (h, w) = text
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{text}` is not HEIGHTxWIDTH, e.g. 256x512"))?;
    let number = |s: &str| {
        s.trim()
            .parse::<usize>()
            .map_err(|_| format!("`{text}` is not HEIGHTxWIDTH, e.g. 256x512"))
    };
    Ok((number(h)?, number(w)?))
}

/// A `LOW:HIGH` range of fractions, `0 < LOW <= HIGH < 1`, such as
/// `0.05:0.15`.
pub fn fraction_range(text: &str) -> Result<(f32, f32), String> {
    let usage = || format!("`{text}` is not LOW:HIGH with 0 < LOW <= HIGH < 1, e.g. 0.05:0.15");
    let (low, high) = text.split_once(':').ok_or_else(usage)?;
    let number = |s: &str| s.trim().parse::<f32>().map_err(|_| usage());
    let (low, high) = (number(low)?, number(high)?);
    if !(0.0 < low && low <= high && high < 1.0) {
        return Err(usage());
    }
    Ok((low, high))
}

/// A scoring protocol's name, as `--protocol` takes it: `--help` lists
/// [`Protocol::EVERY`]'s names, and a wrong one is refused with them.
pub fn protocol() -> impl clap::builder::TypedValueParser<Value = Protocol> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(Protocol::EVERY.map(Protocol::name))
        .try_map(|name| name.parse::<Protocol>())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fraction_ranges_are_ordered_and_inside_0_1() {
        assert_eq!(fraction_range("0.05:0.15"), Ok((0.05, 0.15)));
        assert_eq!(fraction_range("0.1:0.1"), Ok((0.1, 0.1)));
        for bad in ["0.2:0.1", "0:0.1", "0.1:1", "0.1", "a:b", "NaN:0.1"] {
            assert!(
                fraction_range(bad).unwrap_err().contains("LOW:HIGH"),
                "{bad}"
            );
        }
    }

    #[test]
    fn values_outside_their_range_are_refused_with_the_range() {
        assert_eq!(positive("480"), Ok(480.0));
        for bad in ["0", "-5", "NaN", "inf", "x"] {
            let err = positive(bad).unwrap_err();
            assert!(err.contains(bad) && err.contains("above 0"), "{err}");
        }
        assert!(positive_f32("1e300").is_err());
        assert_eq!(jobs("0"), Ok(0));
        assert!(jobs("100000").unwrap_err().contains("from 0 to 1024"));
        assert!(views("100000000").unwrap_err().contains("from 2 to 64"));
        assert!(
            image_side("100000")
                .unwrap_err()
                .contains("from 1 to 32768")
        );
        assert!(count("0").is_err());
        assert_eq!(folder_name("Town01").as_deref(), Ok("Town01"));
        for bad in ["../../x", "a/b", "..", ""] {
            assert!(folder_name(bad).is_err(), "{bad}");
        }
    }
}
