//! The captioned two-row contact sheets of synthesised sets: an
//! extrapolated frame (four views, synthesised pixels, disparities and
//! their colour bar) and a set made from one photo.

use image::Rgb;
use mbs_core::{FloatImage, MaskImage, RgbImage};

use crate::VizError;
use crate::colormap::{colorize_disparity, disparity_scale};
use crate::labelled::{Key, Panel, labelled_grid};

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

/// The contact sheet of one extrapolated frame, two rows of four captioned
/// panels: `image_1, image_2, image_3, image_4`, then `image_1` tinted red
/// where `masks[0]` marks synthesised pixels, the two disparities (one
/// colour scale), and `image_4` tinted by `masks[1]`; below them, a colour
/// bar of the disparity scale in pixels. The layout is that of
/// [`labelled_grid`]. Every input has the size of `views[0]`; another size
/// is an error.
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
    let max = disparity_scale(disparities);
    let tinted = [tint(views[0], masks[0]), tint(views[3], masks[1])];
    let coloured = disparities.map(|d| colorize_disparity(d, max));
    let top = [
        Panel::new(views[0], "new view image_1"),
        Panel::new(views[1], "input (left, image_2)"),
        Panel::new(views[2], "input (right, image_3)"),
        Panel::new(views[3], "new view image_4"),
    ];
    let bottom = [
        Panel::new(&tinted[0], "image_1: synthesised pixels (red)"),
        Panel::new(&coloured[0], "disparity image_2 (px)"),
        Panel::new(&coloured[1], "disparity image_3 (px)"),
        Panel::new(&tinted[1], "image_4: synthesised pixels (red)"),
    ];
    let key = Key::DisparityBar {
        title: "disparity of image_2 and image_3 (px)".into(),
        max,
    };
    labelled_grid(&[&top, &bottom], &[key])
}

/// The contact sheet of a set made from one photo, two rows of one
/// captioned panel per camera: every view (the photo at `reference`),
/// then each synthesised view tinted red where `masks` marks synthesised
/// pixels, with the photo's `disparity` (one baseline's) in the
/// reference's place; below them, its colour bar. Every input has the
/// photo's size; another size, or a mask list of another length, is an
/// error.
pub fn photo_set_sheet(
    views: &[&RgbImage],
    reference: usize,
    masks: &[Option<&MaskImage>],
    disparity: &FloatImage,
) -> Result<RgbImage, VizError> {
    let size = disparity.dimensions();
    let sizes = views
        .iter()
        .map(|v| v.dimensions())
        .chain(masks.iter().flatten().map(|m| m.dimensions()));
    if let Some(other) = sizes.into_iter().find(|s| *s != size) {
        return Err(VizError::Input(format!(
            "a tile is {other:?} but the disparity is {size:?} (width, height)"
        )));
    }
    if masks.len() != views.len() || reference >= views.len() {
        return Err(VizError::Input(format!(
            "{} views, {} masks and reference {reference} do not make one set",
            views.len(),
            masks.len()
        )));
    }
    let max = disparity_scale([disparity]);
    let coloured = colorize_disparity(disparity, max);
    let lower: Vec<RgbImage> = views
        .iter()
        .zip(masks)
        .map(|(view, mask)| mask.map_or_else(|| coloured.clone(), |m| tint(view, m)))
        .collect();
    let captions: Vec<(String, String)> = (0..views.len())
        .map(|k| match k == reference {
            true => (
                format!("photo image_{}", k + 1),
                format!("disparity image_{} (px)", k + 1),
            ),
            false => (
                format!("new view image_{}", k + 1),
                format!("image_{}: synthesised (red)", k + 1),
            ),
        })
        .collect();
    let top: Vec<Panel> = views
        .iter()
        .zip(&captions)
        .map(|(view, (caption, _))| Panel::new(view, caption))
        .collect();
    let bottom: Vec<Panel> = lower
        .iter()
        .zip(&captions)
        .map(|(image, (_, caption))| Panel::new(image, caption))
        .collect();
    let key = Key::DisparityBar {
        title: format!("disparity of image_{}, one baseline (px)", reference + 1),
        max,
    };
    labelled_grid(&[&top, &bottom], &[key])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colormap::turbo;

    /// A picture whose every pixel differs from its neighbours.
    fn picture(width: u32, height: u32, seed: u8) -> RgbImage {
        RgbImage::from_fn(width, height, |x, y| {
            Rgb([(x * 5 + y) as u8 ^ seed, (y * 11 + x) as u8, seed])
        })
    }

    /// The top left corner of the only place where `tile` lies in `sheet`.
    fn find(sheet: &RgbImage, tile: &RgbImage) -> (u32, u32) {
        let (w, h) = tile.dimensions();
        let places: Vec<(u32, u32)> = (0..=sheet.height() - h)
            .flat_map(|y| (0..=sheet.width() - w).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                tile.enumerate_pixels()
                    .all(|(i, j, p)| sheet.get_pixel(x + i, y + j) == p)
            })
            .collect();
        assert_eq!(places.len(), 1, "{places:?}");
        places[0]
    }

    /// Pixels darker than 110 in every channel (text) in the rectangle.
    fn dark(image: &RgbImage, (x, y): (u32, u32), (w, h): (u32, u32)) -> usize {
        (y..y + h)
            .flat_map(|y| (x..x + w).map(move |x| (x, y)))
            .filter(|&(x, y)| image.get_pixel(x, y).0.iter().all(|&c| c < 110))
            .count()
    }

    #[test]
    fn photo_set_tiles_are_each_camera_and_its_mask() {
        let (w, h) = (96, 40);
        let views: Vec<RgbImage> = (0..3).map(|i| picture(w, h, 60 * i)).collect();
        let mut mask = MaskImage::new(w, h);
        mask.put_pixel(3, 4, image::Luma([255]));
        let disparity = FloatImage::from_fn(w, h, |x, _| image::Luma([0.2 * x as f32]));
        let refs: Vec<&RgbImage> = views.iter().collect();
        let masks = [Some(&mask), None, Some(&mask)];
        let sheet = photo_set_sheet(&refs, 1, &masks, &disparity).unwrap();
        for view in &views {
            find(&sheet, view);
        }
        find(&sheet, &tint(&views[0], &mask));
        find(&sheet, &tint(&views[2], &mask));
        let max = disparity_scale([&disparity]);
        find(&sheet, &colorize_disparity(&disparity, max));
        let err = photo_set_sheet(&refs, 3, &masks, &disparity).unwrap_err();
        assert!(
            err.to_string().contains("reference 3 do not make one set"),
            "{err}"
        );
    }

    #[test]
    fn extrapolation_tiles_land_in_their_cells_under_captions() {
        let (w, h) = (160, 64);
        let views: Vec<RgbImage> = (0..4).map(|i| picture(w, h, 40 * i)).collect();
        let mut mask = MaskImage::new(w, h);
        mask.put_pixel(0, 0, image::Luma([255]));
        let disparity = |s: f32| FloatImage::from_fn(w, h, |x, _| image::Luma([s * x as f32]));
        let (left, right) = (disparity(0.1), disparity(0.05));
        let [a, b, c, d] = [&views[0], &views[1], &views[2], &views[3]];
        let sheet = extrapolation_sheet([a, b, c, d], [&mask, &mask], [&left, &right]).unwrap();

        let tinted = tint(a, &mask);
        let Rgb([r, g, bl]) = *a.get_pixel(0, 0);
        assert_eq!(tinted.get_pixel(0, 0).0, [r / 2 + 128, g / 2, bl / 2]);
        assert_eq!(tinted.get_pixel(1, 0), a.get_pixel(1, 0)); // not in the mask
        let max = 0.1 * (w - 1) as f32;
        let tiles = [
            a.clone(),
            b.clone(),
            c.clone(),
            d.clone(),
            tinted,
            colorize_disparity(&left, max),
            colorize_disparity(&right, max),
            tint(d, &mask),
        ];
        let corners: Vec<(u32, u32)> = tiles.iter().map(|t| find(&sheet, t)).collect();
        // Two rows of four, columns aligned, a gap between columns and a
        // caption strip with text above every tile.
        let step = corners[1].0 - corners[0].0;
        assert!(step > w && step < w + 20, "{corners:?}");
        for (i, &(x, y)) in corners.iter().enumerate() {
            let (column, row) = (i as u32 % 4, i / 4);
            assert_eq!(x, column * step, "tile {i}");
            assert_eq!(y, corners[4 * row].1, "tile {i}");
            assert!(
                dark(&sheet, (x, y - 15), (w, 15)) > 20,
                "caption of tile {i}"
            );
        }
        let bottom = corners[4].1 + h;
        assert!(corners[0].1 > 15 && corners[4].1 > corners[0].1 + h + 15);
        // The colour bar below: both ends of the scale, and text.
        let below: Vec<[u8; 3]> = (bottom..sheet.height())
            .flat_map(|y| (0..sheet.width()).map(move |x| (x, y)))
            .map(|(x, y)| sheet.get_pixel(x, y).0)
            .collect();
        for end in [turbo(0.0), turbo(1.0)] {
            assert!(below.iter().filter(|p| **p == end).count() >= 14, "{end:?}");
        }
        let height = sheet.height() - bottom;
        assert!(dark(&sheet, (0, bottom), (sheet.width(), height)) > 200);
        assert_eq!(sheet.width(), 4 * w + 3 * (step - w));

        let small = FloatImage::new(2, 2);
        let err = extrapolation_sheet([a, b, c, d], [&mask, &mask], [&left, &small]).unwrap_err();
        assert!(err.to_string().contains("(2, 2)"), "{err}");
    }

    #[test]
    fn extrapolation_sheets_of_tiny_views_work() {
        for (w, h) in [(1, 1), (5, 3), (64, 160)] {
            let view = RgbImage::new(w, h);
            let mask = MaskImage::new(w, h);
            let disparity = FloatImage::new(w, h);
            let sheet = extrapolation_sheet([&view; 4], [&mask; 2], [&disparity; 2]).unwrap();
            assert!(sheet.width() >= 4 * w && sheet.height() > 2 * h);
        }
    }
}
