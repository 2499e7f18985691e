//! Lines of text drawn straight into RGB images, in the embedded font of
//! the charts: the captions and keys of labelled sheets.

use mbs_core::RgbImage;
use plotters::style::{FontDesc, FontFamily, FontStyle};

use crate::VizError;
use crate::chart::{FONT, register_embedded_font};

/// The embedded font at `size` pixels (ascent plus descent).
fn font(size: f64) -> FontDesc<'static> {
    register_embedded_font();
    FontDesc::new(FontFamily::from(FONT), size, FontStyle::Normal)
}

/// The height of one line of text at `size`, gap included.
pub(crate) fn line_height(size: f64) -> u32 {
    (1.2 * size).ceil() as u32
}

/// The width in pixels of `text` drawn at `size` (the sum of the glyphs'
/// advances, plus one pixel for the last glyph's overhang).
pub(crate) fn text_width(text: &str, size: f64) -> Result<u32, VizError> {
    if text.is_empty() {
        return Ok(0);
    }
    let (width, _) = font(size)
        .box_size(text)
        .map_err(|e| VizError::Draw(format!("cannot lay out {text:?}: {e}")))?;
    Ok(width + 1)
}

/// Draws `text` at `size` in `colour` over `image`, blended by the glyphs'
/// coverage, with its line (of [`line_height`]) starting at row `top` and
/// its first glyph at column `left`. Pixels outside the image are skipped.
pub(crate) fn draw_text(
    image: &mut RgbImage,
    text: &str,
    (left, top): (i32, i32),
    size: f64,
    colour: [u8; 3],
) -> Result<(), VizError> {
    if text.is_empty() {
        return Ok(());
    }
    let (width, height) = (image.width() as i32, image.height() as i32);
    // The font puts the baseline half a size below the given point; the
    // baseline goes 0.9 sizes below the top of the line, which leaves the
    // ascent (0.8 sizes) and a little space above it.
    let origin = (left, top + (0.4 * size).round() as i32);
    let drawn = font(size).draw(text, origin, |x, y, coverage| {
        if (0..width).contains(&x) && (0..height).contains(&y) {
            let a = coverage.clamp(0.0, 1.0);
            let px = image.get_pixel_mut(x as u32, y as u32);
            for (c, ink) in px.0.iter_mut().zip(colour) {
                *c = (f32::from(*c) * (1.0 - a) + f32::from(ink) * a).round() as u8;
            }
        }
        Ok::<(), ()>(())
    });
    match drawn {
        Ok(_) => Ok(()),
        Err(e) => Err(VizError::Draw(format!("cannot draw {text:?}: {e}"))),
    }
}

/// `text` broken at spaces into lines at most `width` pixels wide at
/// `size`. A word wider than `width` gets a line of its own.
pub(crate) fn wrap(text: &str, width: u32, size: f64) -> Result<Vec<String>, VizError> {
    let mut lines: Vec<String> = Vec::new();
    for word in text.split_whitespace() {
        if let Some(line) = lines.last_mut() {
            let longer = format!("{line} {word}");
            if text_width(&longer, size)? <= width {
                *line = longer;
                continue;
            }
        }
        lines.push(word.to_string());
    }
    Ok(lines)
}

/// The width of the widest word of `text` at `size`.
pub(crate) fn widest_word(text: &str, size: f64) -> Result<u32, VizError> {
    text.split_whitespace()
        .map(|word| text_width(word, size))
        .try_fold(0, |widest, w| Ok(widest.max(w?)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows and columns of the pixels darker than 110 in every channel.
    fn ink(image: &RgbImage) -> Vec<(u32, u32)> {
        image
            .enumerate_pixels()
            .filter(|(_, _, p)| p.0.iter().all(|&c| c < 110))
            .map(|(x, y, _)| (x, y))
            .collect()
    }

    #[test]
    fn text_stays_inside_its_line_and_measured_width() {
        for size in [9.0, 15.0, 40.0] {
            let line = line_height(size);
            let text = "Ajgy|(px) ω";
            let width = text_width(text, size).unwrap();
            let mut image = RgbImage::from_pixel(width + 20, 3 * line, image::Rgb([255; 3]));
            draw_text(&mut image, text, (10, line as i32), size, [0, 0, 0]).unwrap();
            let ink = ink(&image);
            assert!(
                ink.len() as f64 > 4.0 * size,
                "{size}: {} pixels",
                ink.len()
            );
            for (x, y) in ink {
                assert!((10..10 + width).contains(&x), "{size}: column {x}");
                assert!((line..2 * line).contains(&y), "{size}: row {y}");
            }
        }
    }

    #[test]
    fn wrapping_breaks_at_spaces() {
        let size = 15.0;
        let two = text_width("teacher disparity", size).unwrap();
        assert_eq!(
            wrap("teacher disparity (px)", two, size).unwrap(),
            ["teacher disparity", "(px)"]
        );
        assert_eq!(
            wrap("teacher disparity", 1, size).unwrap(),
            ["teacher", "disparity"]
        );
        assert!(wrap("  ", 100, size).unwrap().is_empty());
        assert_eq!(
            widest_word("a disparity b", size).unwrap(),
            text_width("disparity", size).unwrap()
        );
    }
}
