//! Image-quality measures between two views, optionally restricted to a mask.

use rayon::prelude::*;

use mbs_core::{MaskImage, RgbImage};

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

/// Radius of the SSIM window: 11 x 11 taps.
const SSIM_RADIUS: usize = 5;
/// Standard deviation (px) of the Gaussian SSIM window.
const SSIM_SIGMA: f64 = 1.5;

/// Structural similarity (Wang et al. 2004) between two RGB images: Gaussian
/// 11 x 11 window with sigma 1.5, `C1 = (0.01 * 255)^2`, `C2 = (0.03 * 255)^2`,
/// borders reflected without repeating the edge pixel (OpenCV's default
/// `BORDER_REFLECT_101`). The SSIM map is averaged over the colour channels,
/// then over the pixels where `mask` is set, or all pixels when `mask` is
/// `None`. Returns `None` when no pixel is counted or the sizes differ.
pub fn ssim(a: &RgbImage, b: &RgbImage, mask: Option<&MaskImage>) -> Option<f64> {
    if a.dimensions() != b.dimensions() || mask.is_some_and(|m| m.dimensions() != a.dimensions()) {
        return None;
    }
    let (w, h) = (a.width() as usize, a.height() as usize);
    let n = w * h;
    let mut map = vec![0.0f64; n];
    let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
    for c in 0..3 {
        let channel = |img: &RgbImage| -> Vec<f64> {
            img.as_raw()
                .iter()
                .skip(c)
                .step_by(3)
                .map(|v| f64::from(*v))
                .collect()
        };
        let (x, y) = (channel(a), channel(b));
        let product =
            |p: &[f64], q: &[f64]| -> Vec<f64> { p.iter().zip(q).map(|(u, v)| u * v).collect() };
        let [mx, my, xx, yy, xy] = [
            x.clone(),
            y.clone(),
            product(&x, &x),
            product(&y, &y),
            product(&x, &y),
        ]
        .map(|plane| gaussian_blur(&plane, w, h));
        map.par_iter_mut().enumerate().for_each(|(i, m)| {
            let (vx, vy) = (xx[i] - mx[i] * mx[i], yy[i] - my[i] * my[i]);
            let cov = xy[i] - mx[i] * my[i];
            let num = (2.0 * mx[i] * my[i] + c1) * (2.0 * cov + c2);
            let den = (mx[i] * mx[i] + my[i] * my[i] + c1) * (vx + vy + c2);
            *m += num / den / 3.0;
        });
    }
    let counted: Vec<f64> = map
        .iter()
        .enumerate()
        .filter(|(i, _)| mask.is_none_or(|m| m.as_raw()[*i] != 0))
        .map(|(_, v)| *v)
        .collect();
    (!counted.is_empty()).then(|| counted.iter().sum::<f64>() / counted.len() as f64)
}

/// Separable Gaussian blur of a `w x h` plane with the SSIM window.
fn gaussian_blur(plane: &[f64], w: usize, h: usize) -> Vec<f64> {
    let taps: Vec<f64> = (0..=2 * SSIM_RADIUS)
        .map(|i| {
            let d = i as f64 - SSIM_RADIUS as f64;
            (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp()
        })
        .collect();
    let total: f64 = taps.iter().sum();
    let taps: Vec<f64> = taps.iter().map(|t| t / total).collect();
    let blur = |len: usize, at: &dyn Fn(usize) -> f64, i: usize| -> f64 {
        taps.iter()
            .enumerate()
            .map(|(k, t)| {
                t * at(reflect101(
                    i as isize + k as isize - SSIM_RADIUS as isize,
                    len,
                ))
            })
            .sum()
    };
    let mut rows = vec![0.0; w * h];
    rows.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, out)| {
            let src = &plane[y * w..(y + 1) * w];
            for (x, o) in out.iter_mut().enumerate() {
                *o = blur(w, &|i| src[i], x);
            }
        });
    let mut out = vec![0.0; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, dst)| {
            for (x, o) in dst.iter_mut().enumerate() {
                *o = blur(h, &|j| rows[j * w + x], y);
            }
        });
    out
}

/// Index `i` reflected into `0..len` without repeating the edge (`-1 -> 1`).
fn reflect101(i: isize, len: usize) -> usize {
    if len == 1 {
        return 0;
    }
    let period = 2 * (len as isize - 1);
    let m = i.rem_euclid(period);
    (if m < len as isize { m } else { period - m }) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ssim_is_one_for_identical_images_and_drops_with_noise() {
        let a = RgbImage::from_fn(32, 24, |x, y| {
            image::Rgb([(x * 8) as u8, (y * 10) as u8, 90])
        });
        assert!((ssim(&a, &a, None).unwrap() - 1.0).abs() < 1e-12);
        // A constant offset of 20 on a flat image: luminance term only,
        // (2 * 100 * 120 + C1) / (100^2 + 120^2 + C1) = 0.98366 (C1 = 6.5025).
        let flat = RgbImage::from_pixel(16, 16, image::Rgb([100; 3]));
        let brighter = RgbImage::from_pixel(16, 16, image::Rgb([120; 3]));
        let expected =
            (2.0 * 100.0 * 120.0 + 6.5025) / (100.0f64.powi(2) + 120.0f64.powi(2) + 6.5025);
        assert!((ssim(&flat, &brighter, None).unwrap() - expected).abs() < 1e-9);
        let noisy = RgbImage::from_fn(32, 24, |x, y| {
            let p = a.get_pixel(x, y).0;
            let n = if (x * 7 + y * 13) % 3 == 0 { 40 } else { 0 };
            image::Rgb(p.map(|v| v.saturating_add(n)))
        });
        let s = ssim(&a, &noisy, None).unwrap();
        // The same formula on cv2.GaussianBlur planes (numpy) gives
        // 0.38916217543893 (tools/bench/extrapolate_vs_numpy.py, `ssim`).
        assert!((s - 0.389_162_175_438_93).abs() < 1e-9, "{s}");
        assert_eq!(ssim(&a, &noisy, Some(&MaskImage::new(32, 24))), None);
        assert_eq!(reflect101(-1, 5), 1);
        assert_eq!(reflect101(5, 5), 3);
    }

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
