//! The occlusion-aware weight map of the paper drawn over the reference
//! image: which pixels the student learns from, and how strongly.

use mbs_core::RgbImage;

use crate::VizError;
use crate::labelled::Key;

/// Brightness of the grey-scale reference under the weight map.
const DARKEN: f32 = 0.35;
/// Weight 0: the teacher's mask is off (teacher occluded or unreliable).
pub const TEACHER_INVALID: [u8; 3] = [230, 40, 40];
/// Weight omega: the teacher's mask is on and the student's is off
/// (occluded in the student's target only).
pub const STUDENT_ONLY_INVALID: [u8; 3] = [40, 210, 60];

/// The swatch of weight 1 in [`weight_map_key`]: a white reference at
/// [`DARKEN`] brightness (darker references give darker greys).
const BOTH_VALID_SWATCH: [u8; 3] = [89, 89, 89];

/// The key to the colours of [`weight_map_image`], for a labelled sheet.
pub fn weight_map_key() -> Key {
    Key::Swatches {
        title: "weight map A".into(),
        entries: vec![
            (
                TEACHER_INVALID,
                "A = 0: teacher mask off (occluded or unreliable)".into(),
            ),
            (
                STUDENT_ONLY_INVALID,
                "A = ω: only the student's mask off".into(),
            ),
            (
                BOTH_VALID_SWATCH,
                "A = 1: both masks on (reference in grey)".into(),
            ),
        ],
    }
}

/// The paper's picture of the occlusion-aware weight map A over the
/// reference image: red where the teacher mask is 0 (A = 0), green where
/// the teacher mask is 1 and the student mask 0 (A = omega), and the
/// reference in grey at 35 % brightness where both are 1 (A = 1).
///
/// Masks are row-major `height * width` values in {0, 1}; a value counts as
/// 1 from 0.5 up (NaN counts as 0). A mask of another length is an error.
pub fn weight_map_image(
    reference: &RgbImage,
    teacher_mask: &[f32],
    student_mask: &[f32],
) -> Result<RgbImage, VizError> {
    let (w, h) = reference.dimensions();
    let n = w as usize * h as usize;
    for (name, mask) in [("teacher", teacher_mask), ("student", student_mask)] {
        if mask.len() != n {
            return Err(VizError::Input(format!(
                "the {name} mask has {} values, but the {w}x{h} reference needs {n}",
                mask.len()
            )));
        }
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

#[cfg(test)]
mod tests {
    use super::*;

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
    fn the_key_shows_the_three_colours() {
        let Key::Swatches { entries, .. } = weight_map_key() else {
            panic!("the weight map key is a list of swatches");
        };
        let colours: Vec<[u8; 3]> = entries.iter().map(|(c, _)| *c).collect();
        let white = RgbImage::from_pixel(1, 1, image::Rgb([255; 3]));
        let both = weight_map_image(&white, &[1.0], &[1.0]).unwrap();
        assert_eq!(
            colours,
            [
                TEACHER_INVALID,
                STUDENT_ONLY_INVALID,
                both.get_pixel(0, 0).0
            ]
        );
        assert!(entries[0].1.starts_with("A = 0") && entries[1].1.starts_with("A = ω"));
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
}
