//! A contact sheet of one extrapolated frame: the four views on top
//! (synthesised pixels of the new views tinted red below them) and the
//! disparities used, colour-mapped.

use image::{GenericImage, Rgb};
use mbs_core::colormap::colorize_disparity;
use mbs_core::{FloatImage, MaskImage, RgbImage};

/// Tints the pixels set in `mask` towards red.
fn tint(view: &RgbImage, mask: &MaskImage) -> RgbImage {
    let mut out = view.clone();
    for (px, m) in out.pixels_mut().zip(mask.as_raw()) {
        if *m != 0 {
            let Rgb([r, g, b]) = *px;
            *px = Rgb([r / 2 + 128, g / 2, b / 2]);
        }
    }
    out
}

/// Two rows of four tiles: `image_1, image_2, image_3, image_4`, then
/// `image_1` tinted by its mask, the two disparities, `image_4` tinted.
pub fn contact_sheet(
    views: [&RgbImage; 4],
    masks: [&MaskImage; 2],
    disparities: [&FloatImage; 2],
) -> RgbImage {
    let (w, h) = views[0].dimensions();
    let max = disparities
        .iter()
        .flat_map(|d| d.iter())
        .filter(|d| d.is_finite())
        .fold(1.0f32, |m, &d| m.max(d));
    let bottom = [
        tint(views[0], masks[0]),
        colorize_disparity(disparities[0], max),
        colorize_disparity(disparities[1], max),
        tint(views[3], masks[1]),
    ];
    let mut sheet = RgbImage::new(4 * w, 2 * h);
    let tiles = views.into_iter().chain(bottom.iter());
    for (i, tile) in tiles.enumerate() {
        let (x, y) = ((i as u32 % 4) * w, (i as u32 / 4) * h);
        // Every tile has the frame's size, so it fits its cell.
        sheet.copy_from(tile, x, y).expect("tile fits the sheet");
    }
    sheet
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_land_in_their_cells() {
        let view = |v: u8| RgbImage::from_pixel(3, 2, Rgb([v, v, v]));
        let (a, b, c, d) = (view(10), view(20), view(30), view(40));
        let mut mask = MaskImage::new(3, 2);
        mask.put_pixel(0, 0, image::Luma([255]));
        let disp = FloatImage::from_pixel(3, 2, image::Luma([1.0]));
        let sheet = contact_sheet([&a, &b, &c, &d], [&mask, &mask], [&disp, &disp]);
        assert_eq!(sheet.dimensions(), (12, 4));
        assert_eq!(sheet.get_pixel(4, 0).0, [20; 3]);
        assert_eq!(sheet.get_pixel(9, 1).0, [40; 3]);
        assert_eq!(sheet.get_pixel(0, 2).0, [133, 5, 5]); // tinted
        assert_eq!(sheet.get_pixel(1, 2).0, [10; 3]); // not in the mask
    }
}
