//! Bilinear resizing of float maps (the `image` crate's resize clamps float
//! pixels to 0..=1, which disparities are not).

use mbs_core::FloatImage;

/// `map` resized to `width` x `height` by bilinear interpolation with
/// pixel centres aligned (PyTorch's `align_corners = false`), edges clamped.
pub fn resize_bilinear(map: &FloatImage, width: u32, height: u32) -> FloatImage {
    let (sw, sh) = map.dimensions();
    // For each output coordinate: the two source indices and the weight of
    // the second.
    let taps = |n: u32, src: u32| -> Vec<(usize, usize, f32)> {
        let ratio = src as f32 / n as f32;
        (0..n)
            .map(|i| {
                let s = ((i as f32 + 0.5) * ratio - 0.5).clamp(0.0, (src - 1) as f32);
                let i0 = s.floor() as usize;
                let i1 = (i0 + 1).min(src as usize - 1);
                (i0, i1, s - i0 as f32)
            })
            .collect()
    };
    let xs = taps(width, sw);
    let ys = taps(height, sh);
    let src = map.as_raw();
    let row = |y: usize| &src[y * sw as usize..][..sw as usize];
    let mut out = Vec::with_capacity(width as usize * height as usize);
    for &(y0, y1, wy) in &ys {
        let (r0, r1) = (row(y0), row(y1));
        for &(x0, x1, wx) in &xs {
            let top = r0[x0] + wx * (r0[x1] - r0[x0]);
            let bottom = r1[x0] + wx * (r1[x1] - r1[x0]);
            out.push(top + wy * (bottom - top));
        }
    }
    FloatImage::from_raw(width, height, out).expect("one value per output pixel by construction")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_stay_constant_and_ramps_stay_ramps() {
        let constant = FloatImage::from_pixel(6, 4, image::Luma([61.0]));
        assert!(resize_bilinear(&constant, 12, 8).iter().all(|&v| v == 61.0));
        let ramp = FloatImage::from_fn(4, 1, |x, _| image::Luma([x as f32 * 10.0]));
        let up = resize_bilinear(&ramp, 8, 1);
        assert_eq!(up.as_raw(), &[0.0, 2.5, 7.5, 12.5, 17.5, 22.5, 27.5, 30.0]);
    }
}
