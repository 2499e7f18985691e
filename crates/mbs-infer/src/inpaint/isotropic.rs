//! Isotropic rim-inwards fill ("onion peel"), a Telea-like reference: each
//! masked pixel becomes the distance-weighted mean of its already-known
//! 8-neighbours, one ring of the hole at a time.

use mbs_core::{FloatImage, MaskImage, RgbImage};

use super::{Canvas, InpaintError, Inpainter, check_inputs};

/// Fills holes from their whole rim inwards, ignoring depth: background and
/// foreground colours blend in the middle of a disocclusion.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct IsotropicFill;

/// The 8-neighbourhood with weights: 1 for edge neighbours, 1/sqrt(2) for
/// diagonal ones.
const NEIGHBOURS: [(isize, isize, f32); 8] = [
    (-1, 0, 1.0),
    (1, 0, 1.0),
    (0, -1, 1.0),
    (0, 1, 1.0),
    (-1, -1, std::f32::consts::FRAC_1_SQRT_2),
    (1, -1, std::f32::consts::FRAC_1_SQRT_2),
    (-1, 1, std::f32::consts::FRAC_1_SQRT_2),
    (1, 1, std::f32::consts::FRAC_1_SQRT_2),
];

impl Inpainter for IsotropicFill {
    fn name(&self) -> &str {
        "isotropic-fill"
    }

    fn inpaint(
        &self,
        image: &RgbImage,
        mask: &MaskImage,
        disparity: Option<&FloatImage>,
    ) -> Result<RgbImage, InpaintError> {
        check_inputs(image, mask, disparity)?;
        let mut canvas = Canvas::new(image, mask);
        peel(&mut canvas)?;
        Ok(canvas.into_image())
    }
}

/// Fills every unknown pixel of `canvas`, ring by ring from the known ones.
pub(super) fn peel(canvas: &mut Canvas) -> Result<(), InpaintError> {
    let (w, h) = (canvas.width, canvas.height);
    if canvas.known.iter().all(|k| *k) {
        return Ok(());
    }
    if !canvas.known.iter().any(|k| *k) {
        return Err(InpaintError::NothingKnown(w as u32, h as u32));
    }
    let neighbours = |i: usize| {
        let (x, y) = ((i % w) as isize, (i / w) as isize);
        NEIGHBOURS.iter().filter_map(move |&(dx, dy, wt)| {
            let (nx, ny) = (x + dx, y + dy);
            (nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h)
                .then(|| (ny as usize * w + nx as usize, wt))
        })
    };
    let mut queued = vec![false; w * h];
    let mut ring: Vec<usize> = (0..w * h)
        .filter(|&i| !canvas.known[i] && neighbours(i).any(|(n, _)| canvas.known[n]))
        .collect();
    ring.iter().for_each(|&i| queued[i] = true);
    let mut values = Vec::new();
    while !ring.is_empty() {
        values.clear();
        for &i in &ring {
            let mut sum = [0.0f32; 3];
            let mut weight = 0.0;
            for (n, wt) in neighbours(i).filter(|(n, _)| canvas.known[*n]) {
                for (s, v) in sum.iter_mut().zip(canvas.rgb[n]) {
                    *s += wt * v;
                }
                weight += wt;
            }
            values.push(sum.map(|s| s / weight));
        }
        let mut next = Vec::new();
        for (&i, v) in ring.iter().zip(&values) {
            canvas.rgb[i] = *v;
            canvas.known[i] = true;
        }
        for &i in &ring {
            for (n, _) in neighbours(i) {
                if !canvas.known[n] && !queued[n] {
                    queued[n] = true;
                    next.push(n);
                }
            }
        }
        ring = next;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fills_a_hole_with_the_rim_colour_and_keeps_known_pixels() {
        let mut image = RgbImage::from_pixel(7, 7, image::Rgb([40, 80, 120]));
        let mut mask = MaskImage::new(7, 7);
        for y in 2..5 {
            for x in 2..5 {
                image.put_pixel(x, y, image::Rgb([0, 0, 0]));
                mask.put_pixel(x, y, image::Luma([255]));
            }
        }
        let out = IsotropicFill.inpaint(&image, &mask, None).unwrap();
        assert!(out.pixels().all(|p| p.0 == [40, 80, 120]));
    }

    #[test]
    fn blends_two_sides_and_rejects_bad_inputs() {
        // Left half 0, right half 200, a 2-pixel hole in between: symmetric.
        let image = RgbImage::from_fn(6, 1, |x, _| image::Rgb([if x < 3 { 0 } else { 200 }; 3]));
        let mask = MaskImage::from_raw(6, 1, vec![0, 0, 255, 255, 0, 0]).unwrap();
        let out = IsotropicFill.inpaint(&image, &mask, None).unwrap();
        assert_eq!(out.get_pixel(2, 0).0[0], 0);
        assert_eq!(out.get_pixel(3, 0).0[0], 200);
        let all = MaskImage::from_pixel(6, 1, image::Luma([255]));
        assert_eq!(
            IsotropicFill.inpaint(&image, &all, None),
            Err(InpaintError::NothingKnown(6, 1))
        );
        let err = IsotropicFill
            .inpaint(&image, &MaskImage::new(5, 1), None)
            .unwrap_err();
        assert!(err.to_string().starts_with("mask is (5, 1)"), "{err}");
    }
}
