//! Pictures of a training step: the occlusion-aware weight map as in the
//! paper's figure, and contact sheets of same-height images side by side
//! (reference | teacher disparity | student disparity | GT | weight map; the
//! disparities coloured with [`mbs_core::colormap::colorize_disparity`]).

use anyhow::{bail, ensure};
use image::GenericImage;
use mbs_core::RgbImage;

/// Brightness of the grey-scale reference under the weight map.
const DARKEN: f32 = 0.35;
/// Weight 0: the teacher's mask is off (teacher occluded or unreliable).
const TEACHER_INVALID: [u8; 3] = [230, 40, 40];
/// Weight omega: the teacher's mask is on and the student's is off
/// (occluded in the student's target only).
const STUDENT_ONLY_INVALID: [u8; 3] = [40, 210, 60];
/// Width of the white gap between tiles of a contact sheet.
const GUTTER: u32 = 4;
/// Colour of that gap.
const GUTTER_COLOR: [u8; 3] = [255, 255, 255];

/// The paper's picture of the occlusion-aware weight map A over the
/// reference image: red where the teacher mask is 0 (A = 0), green where
/// the teacher mask is 1 and the student mask 0 (A = omega), and the
/// reference in grey at 35 % brightness where both are 1 (A = 1).
///
/// Masks are row-major `height * width` values in {0, 1}; a value counts as
/// 1 from 0.5 up (NaN counts as 0). A mask of another length is an error.
pub(crate) fn weight_map_image(
    reference: &RgbImage,
    teacher_mask: &[f32],
    student_mask: &[f32],
) -> anyhow::Result<RgbImage> {
    let (w, h) = reference.dimensions();
    let n = w as usize * h as usize;
    for (name, mask) in [("teacher", teacher_mask), ("student", student_mask)] {
        ensure!(
            mask.len() == n,
            "the {name} mask has {} values, but the {w}x{h} reference needs {n}",
            mask.len()
        );
    }
    let on = |v: f32| v >= 0.5;
    Ok(RgbImage::from_fn(w, h, |x, y| {
        let i = y as usize * w as usize + x as usize;
        let rgb = if !on(teacher_mask[i]) {
            TEACHER_INVALID
        } else if !on(student_mask[i]) {
            STUDENT_ONLY_INVALID
        } else {
            let [r, g, b] = reference.get_pixel(x, y).0.map(f32::from);
            let grey = (DARKEN * (0.299 * r + 0.587 * g + 0.114 * b)).round() as u8;
            [grey; 3]
        };
        image::Rgb(rgb)
    }))
}

/// Tiles same-height `images` left to right with a 4-pixel white gap
/// between neighbours. An empty list or differing heights are an error.
pub(crate) fn side_by_side(images: &[&RgbImage]) -> anyhow::Result<RgbImage> {
    let Some(first) = images.first() else {
        bail!("no images to put side by side");
    };
    let height = first.height();
    for (i, img) in images.iter().enumerate() {
        ensure!(
            img.height() == height,
            "image {i} is {} pixels high, image 0 is {height}: side by side needs one height",
            img.height()
        );
    }
    let width =
        images.iter().map(|img| img.width()).sum::<u32>() + GUTTER * (images.len() as u32 - 1);
    let mut sheet = RgbImage::from_pixel(width, height, image::Rgb(GUTTER_COLOR));
    let mut x0 = 0;
    for img in images {
        sheet.copy_from(*img, x0, 0)?;
        x0 += img.width() + GUTTER;
    }
    Ok(sheet)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_core::FloatImage;
    use mbs_core::colormap::colorize_disparity;

    #[test]
    fn weight_map_colours_the_three_cases() {
        // A 2x2 reference: white, mid grey, pure red, black.
        let reference =
            RgbImage::from_raw(2, 2, vec![255, 255, 255, 100, 100, 100, 255, 0, 0, 0, 0, 0])
                .unwrap();
        let teacher = [1.0, 1.0, 0.0, 1.0];
        let student = [1.0, 1.0, 1.0, 0.0];
        let map = weight_map_image(&reference, &teacher, &student).unwrap();
        // Both valid: the reference darkened to 35 % grey.
        assert_eq!(map.get_pixel(0, 0).0, [89, 89, 89]);
        assert_eq!(map.get_pixel(1, 0).0, [35, 35, 35]);
        // Teacher invalid: red, whatever the student says.
        assert_eq!(map.get_pixel(0, 1).0, TEACHER_INVALID);
        // Teacher valid, student invalid: green.
        assert_eq!(map.get_pixel(1, 1).0, STUDENT_ONLY_INVALID);
        let [r, g, b] = TEACHER_INVALID;
        assert!(r > 200 && g < 60 && b < 60);
        let [r, g, b] = STUDENT_ONLY_INVALID;
        assert!(g > 200 && r < 60 && b < 80);

        // Teacher invalid wins over student invalid.
        let map = weight_map_image(&reference, &[0.0; 4], &[0.0; 4]).unwrap();
        assert!(map.pixels().all(|p| p.0 == TEACHER_INVALID));
    }

    #[test]
    fn weight_map_rejects_masks_of_the_wrong_size() {
        let reference = RgbImage::new(3, 2);
        let err = weight_map_image(&reference, &[1.0; 6], &[1.0; 5]).unwrap_err();
        assert!(
            err.to_string().contains("student mask has 5 values"),
            "{err}"
        );
        assert!(err.to_string().contains("3x2"), "{err}");
        assert!(weight_map_image(&reference, &[1.0; 7], &[1.0; 6]).is_err());
    }

    #[test]
    fn side_by_side_tiles_with_white_gutters() {
        // A contact sheet: reference, a coloured disparity, a weight map.
        let reference = RgbImage::from_pixel(3, 2, image::Rgb([10, 20, 30]));
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
