//! Image-quality measures between two views, optionally restricted to a mask.

use crate::{MaskImage, RgbImage};

/// Peak signal-to-noise ratio (dB, peak 255) between two RGB images over the
/// pixels where `mask` is set (non-zero), or over all pixels when `mask` is
/// `None`. Returns `None` when no pixel is counted or the sizes differ;
/// identical images give `f64::INFINITY`.
pub fn psnr(a: &RgbImage, b: &RgbImage, mask: Option<&MaskImage>) -> Option<f64> {
    if a.dimensions() != b.dimensions() || mask.is_some_and(|m| m.dimensions() != a.dimensions()) {
        return None;
    }
    let mut sum = 0.0f64;
    let mut count = 0usize;
    for (i, (pa, pb)) in a.pixels().zip(b.pixels()).enumerate() {
        if mask.is_some_and(|m| m.as_raw()[i] == 0) {
            continue;
        }
        for c in 0..3 {
            let diff = f64::from(pa.0[c]) - f64::from(pb.0[c]);
            sum += diff * diff;
        }
        count += 3;
    }
    if count == 0 {
        return None;
    }
    let mse = sum / count as f64;
    Some(if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psnr_matches_hand_computation() {
        let a = RgbImage::from_raw(2, 1, vec![0, 0, 0, 10, 10, 10]).unwrap();
        let b = RgbImage::from_raw(2, 1, vec![0, 0, 0, 20, 20, 20]).unwrap();
        // MSE over 6 samples = 3 * 100 / 6 = 50.
        let expected = 10.0 * (65025.0f64 / 50.0).log10();
        assert!((psnr(&a, &b, None).unwrap() - expected).abs() < 1e-12);
        let only_first = MaskImage::from_raw(2, 1, vec![255, 0]).unwrap();
        assert_eq!(psnr(&a, &b, Some(&only_first)), Some(f64::INFINITY));
        assert_eq!(psnr(&a, &b, Some(&MaskImage::new(2, 1))), None);
    }
}
