//! Contact sheets: images tiled side by side, and the two-row sheet of an
//! extrapolated frame (four views, synthesised pixels, disparities).

use image::{GenericImage, Rgb};
use mbs_core::{FloatImage, MaskImage, RgbImage};

use crate::VizError;
use crate::colormap::{colorize_disparity, disparity_scale};

/// Width of the white gap between tiles of [`side_by_side`].
const GUTTER: u32 = 4;
/// Colour of that gap.
const GUTTER_COLOR: [u8; 3] = [255, 255, 255];

/// Tiles same-height `images` left to right with a 4-pixel white gap
/// between neighbours. An empty list or differing heights are an error.
pub fn side_by_side(images: &[&RgbImage]) -> Result<RgbImage, VizError> {
    let Some(first) = images.first() else {
        return Err(VizError::Input("no images to put side by side".into()));
    };
    let height = first.height();
    for (i, img) in images.iter().enumerate() {
        if img.height() != height {
            return Err(VizError::Input(format!(
                "image {i} is {} pixels high, image 0 is {height}: side by side needs one height",
                img.height()
            )));
        }
    }
    let width =
        images.iter().map(|img| img.width()).sum::<u32>() + GUTTER * (images.len() as u32 - 1);
    let mut sheet = RgbImage::from_pixel(width, height, Rgb(GUTTER_COLOR));
    let mut x0 = 0;
    for img in images {
        sheet
            .copy_from(*img, x0, 0)
            .map_err(|e| VizError::Draw(e.to_string()))?;
        x0 += img.width() + GUTTER;
    }
    Ok(sheet)
}

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

/// The contact sheet of one extrapolated frame, two rows of four tiles:
/// `image_1, image_2, image_3, image_4`, then `image_1` tinted red where
/// `masks[0]` marks synthesised pixels, the two disparities (one colour
/// scale), and `image_4` tinted by `masks[1]`. Every input has the size of
/// `views[0]`; another size is an error.
pub fn extrapolation_sheet(
    views: [&RgbImage; 4],
    masks: [&MaskImage; 2],
    disparities: [&FloatImage; 2],
) -> Result<RgbImage, VizError> {
    let size = views[0].dimensions();
    let sizes = views
        .iter()
        .map(|v| v.dimensions())
        .chain(masks.iter().map(|m| m.dimensions()))
        .chain(disparities.iter().map(|d| d.dimensions()));
    if let Some(other) = sizes.into_iter().find(|s| *s != size) {
        return Err(VizError::Input(format!(
            "a tile is {other:?} but the first view is {size:?} (width, height)"
        )));
    }
    let (w, h) = size;
    let max = disparity_scale(disparities);
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
        sheet
            .copy_from(tile, x, y)
            .map_err(|e| VizError::Draw(e.to_string()))?;
    }
    Ok(sheet)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::weight_map::{TEACHER_INVALID, weight_map_image};

    #[test]
    fn extrapolation_tiles_land_in_their_cells() {
        let view = |v: u8| RgbImage::from_pixel(3, 2, Rgb([v, v, v]));
        let (a, b, c, d) = (view(10), view(20), view(30), view(40));
        let mut mask = MaskImage::new(3, 2);
        mask.put_pixel(0, 0, image::Luma([255]));
        let disp = FloatImage::from_pixel(3, 2, image::Luma([1.0]));
        let sheet = extrapolation_sheet([&a, &b, &c, &d], [&mask, &mask], [&disp, &disp]).unwrap();
        assert_eq!(sheet.dimensions(), (12, 4));
        assert_eq!(sheet.get_pixel(4, 0).0, [20; 3]);
        assert_eq!(sheet.get_pixel(9, 1).0, [40; 3]);
        assert_eq!(sheet.get_pixel(0, 2).0, [133, 5, 5]); // tinted
        assert_eq!(sheet.get_pixel(1, 2).0, [10; 3]); // not in the mask

        let small = FloatImage::new(2, 2);
        let err =
            extrapolation_sheet([&a, &b, &c, &d], [&mask, &mask], [&disp, &small]).unwrap_err();
        assert!(err.to_string().contains("(2, 2)"), "{err}");
    }

    #[test]
    fn side_by_side_tiles_with_white_gutters() {
        // A contact sheet: reference, a coloured disparity, a weight map.
        let reference = RgbImage::from_pixel(3, 2, Rgb([10, 20, 30]));
        let disparity = FloatImage::from_raw(5, 2, (0..10).map(|v| v as f32).collect()).unwrap();
        let coloured = colorize_disparity(&disparity, 9.0);
        let weights = weight_map_image(&reference, &[0.0; 6], &[0.0; 6]).unwrap();
        let sheet = side_by_side(&[&reference, &coloured, &weights]).unwrap();
        assert_eq!(sheet.dimensions(), (3 + 4 + 5 + 4 + 3, 2));
        for y in 0..2 {
            for x in (3..7).chain(12..16) {
                assert_eq!(
                    sheet.get_pixel(x, y).0,
                    [255, 255, 255],
                    "gutter at {x},{y}"
                );
            }
            assert_eq!(sheet.get_pixel(2, y), reference.get_pixel(2, y));
            for x in 0..5 {
                assert_eq!(sheet.get_pixel(7 + x, y), coloured.get_pixel(x, y));
            }
            assert_eq!(sheet.get_pixel(16, y).0, TEACHER_INVALID);
        }
        // One image: no gutter.
        assert_eq!(side_by_side(&[&reference]).unwrap(), reference);
    }

    #[test]
    fn side_by_side_needs_images_of_one_height() {
        let a = RgbImage::new(2, 2);
        let b = RgbImage::new(2, 3);
        let err = side_by_side(&[&a, &b]).unwrap_err();
        assert!(
            err.to_string().contains("image 1 is 3 pixels high"),
            "{err}"
        );
        assert!(side_by_side(&[]).is_err());
    }
}
