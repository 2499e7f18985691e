//! A built-in 5x7 bitmap font for plot labels: tiny-skia draws shapes, not
//! text, and a font file would be a dependency for a dozen labels. Glyphs
//! follow the classic HD44780 character ROM; each lit cell is drawn as a
//! filled square of `scale` pixels.

use tiny_skia::{Color, Paint, Pixmap, Rect, Transform};

/// Glyph width in font cells.
const GLYPH_W: u32 = 5;
/// Glyph height in font cells, without descenders.
const GLYPH_H: u32 = 7;
/// How far glyphs with a descender are drawn below the others, in font cells.
const DESCENT: u32 = 2;
/// Horizontal distance between the starts of two glyphs, in font cells.
const ADVANCE: u32 = GLYPH_W + 1;

/// Drawn for characters the table lacks: an empty box, so a missing glyph
/// is visible instead of silently dropped.
const MISSING: [u8; 7] = [
    0b11111, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b11111,
];

/// The glyphs: 7 rows top to bottom, bit 4 is the leftmost column.
/// Lower-case letters use rows 2..7; those with a descender are in
/// [`DESCENDERS`].
#[rustfmt::skip]
const GLYPHS: &[(char, [u8; 7])] = &[
    (' ', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000]),
    ('0', [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110]),
    ('1', [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('2', [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111]),
    ('3', [0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110]),
    ('4', [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010]),
    ('5', [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110]),
    ('6', [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110]),
    ('7', [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000]),
    ('8', [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110]),
    ('9', [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100]),
    ('.', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b01100]),
    (',', [0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b00100, 0b01000]),
    ('-', [0b00000, 0b00000, 0b00000, 0b11111, 0b00000, 0b00000, 0b00000]),
    ('+', [0b00000, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0b00000]),
    ('%', [0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011]),
    (':', [0b00000, 0b01100, 0b01100, 0b00000, 0b01100, 0b01100, 0b00000]),
    ('/', [0b00000, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b00000]),
    ('_', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b11111]),
    ('=', [0b00000, 0b00000, 0b11111, 0b00000, 0b11111, 0b00000, 0b00000]),
    ('(', [0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010]),
    (')', [0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000]),
    ('[', [0b01110, 0b01000, 0b01000, 0b01000, 0b01000, 0b01000, 0b01110]),
    (']', [0b01110, 0b00010, 0b00010, 0b00010, 0b00010, 0b00010, 0b01110]),
    ('<', [0b00010, 0b00100, 0b01000, 0b10000, 0b01000, 0b00100, 0b00010]),
    ('>', [0b01000, 0b00100, 0b00010, 0b00001, 0b00010, 0b00100, 0b01000]),
    ('*', [0b00000, 0b00100, 0b10101, 0b01110, 0b10101, 0b00100, 0b00000]),
    ('#', [0b01010, 0b01010, 0b11111, 0b01010, 0b11111, 0b01010, 0b01010]),
    ('!', [0b00100, 0b00100, 0b00100, 0b00100, 0b00000, 0b00000, 0b00100]),
    ('?', [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b00000, 0b00100]),
    ('\'', [0b01100, 0b00100, 0b01000, 0b00000, 0b00000, 0b00000, 0b00000]),
    ('A', [0b01110, 0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001]),
    ('B', [0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110]),
    ('C', [0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110]),
    ('D', [0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100]),
    ('E', [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111]),
    ('F', [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000]),
    ('G', [0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111]),
    ('H', [0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001]),
    ('I', [0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('J', [0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100]),
    ('K', [0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001]),
    ('L', [0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111]),
    ('M', [0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001]),
    ('N', [0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001]),
    ('O', [0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110]),
    ('P', [0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000]),
    ('Q', [0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101]),
    ('R', [0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001]),
    ('S', [0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110]),
    ('T', [0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100]),
    ('U', [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110]),
    ('V', [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100]),
    ('W', [0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010]),
    ('X', [0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001]),
    ('Y', [0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100]),
    ('Z', [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111]),
    ('a', [0b00000, 0b00000, 0b01110, 0b00001, 0b01111, 0b10001, 0b01111]),
    ('b', [0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b11110]),
    ('c', [0b00000, 0b00000, 0b01110, 0b10000, 0b10000, 0b10001, 0b01110]),
    ('d', [0b00001, 0b00001, 0b01101, 0b10011, 0b10001, 0b10001, 0b01111]),
    ('e', [0b00000, 0b00000, 0b01110, 0b10001, 0b11111, 0b10000, 0b01110]),
    ('f', [0b00110, 0b01001, 0b01000, 0b11100, 0b01000, 0b01000, 0b01000]),
    ('h', [0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001]),
    ('i', [0b00100, 0b00000, 0b01100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('j', [0b00010, 0b00000, 0b00110, 0b00010, 0b00010, 0b10010, 0b01100]),
    ('k', [0b10000, 0b10000, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010]),
    ('l', [0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('m', [0b00000, 0b00000, 0b11010, 0b10101, 0b10101, 0b10001, 0b10001]),
    ('n', [0b00000, 0b00000, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001]),
    ('o', [0b00000, 0b00000, 0b01110, 0b10001, 0b10001, 0b10001, 0b01110]),
    ('r', [0b00000, 0b00000, 0b10110, 0b11001, 0b10000, 0b10000, 0b10000]),
    ('s', [0b00000, 0b00000, 0b01110, 0b10000, 0b01110, 0b00001, 0b11110]),
    ('t', [0b01000, 0b01000, 0b11100, 0b01000, 0b01000, 0b01001, 0b00110]),
    ('u', [0b00000, 0b00000, 0b10001, 0b10001, 0b10001, 0b10011, 0b01101]),
    ('v', [0b00000, 0b00000, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100]),
    ('w', [0b00000, 0b00000, 0b10001, 0b10001, 0b10101, 0b10101, 0b01010]),
    ('x', [0b00000, 0b00000, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001]),
    ('z', [0b00000, 0b00000, 0b11111, 0b00010, 0b00100, 0b01000, 0b11111]),
];

/// Lower-case letters with a descender, drawn [`DESCENT`] cells lower than
/// the other glyphs: their x-height is rows 0..5, the descender rows 5..7.
#[rustfmt::skip]
const DESCENDERS: &[(char, [u8; 7])] = &[
    ('g', [0b01111, 0b10001, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110]),
    ('p', [0b11110, 0b10001, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000]),
    ('q', [0b01111, 0b10001, 0b10001, 0b10001, 0b01111, 0b00001, 0b00001]),
    ('y', [0b10001, 0b10001, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110]),
];

/// The rows of `c`'s glyph and how many cells lower it is drawn, or an
/// empty box for a character the font lacks.
fn glyph(c: char) -> ([u8; 7], u32) {
    let find = |table: &[(char, [u8; 7])]| table.iter().find(|(g, _)| *g == c).map(|(_, r)| *r);
    if let Some(rows) = find(GLYPHS) {
        (rows, 0)
    } else if let Some(rows) = find(DESCENDERS) {
        (rows, DESCENT)
    } else {
        (MISSING, 0)
    }
}

/// Width in pixels of `text` drawn at `scale` (no trailing gap).
pub(super) fn text_width(text: &str, scale: u32) -> u32 {
    let n = text.chars().count() as u32;
    (n * ADVANCE).saturating_sub(1) * scale
}

/// Height in pixels of a line of text drawn at `scale`, from the top of a
/// capital to the baseline (descenders reach [`DESCENT`] cells lower).
pub(super) fn text_height(scale: u32) -> u32 {
    GLYPH_H * scale
}

/// Draws `text` with its top-left corner at (`x`, `y`) (rounded to whole
/// pixels, so the cells stay crisp), each font cell `scale` pixels wide.
pub(super) fn draw_text(pixmap: &mut Pixmap, text: &str, x: f32, y: f32, scale: u32, color: Color) {
    let mut paint = Paint::default();
    paint.set_color(color);
    paint.anti_alias = false;
    let (x0, y0, s) = (x.round(), y.round(), scale as f32);
    for (i, c) in text.chars().enumerate() {
        let gx = x0 + (i as u32 * ADVANCE) as f32 * s;
        let (rows, drop) = glyph(c);
        for (row, bits) in rows.iter().enumerate() {
            let row = row as u32 + drop;
            // One rectangle per run of lit cells in the row.
            let mut col = 0;
            while col < GLYPH_W {
                let lit = |col: u32| bits & (1 << (GLYPH_W - 1 - col)) != 0;
                if !lit(col) {
                    col += 1;
                    continue;
                }
                let start = col;
                while col < GLYPH_W && lit(col) {
                    col += 1;
                }
                let cell = Rect::from_xywh(
                    gx + start as f32 * s,
                    y0 + row as f32 * s,
                    (col - start) as f32 * s,
                    s,
                );
                // `None` only for an empty or non-finite rectangle: nothing to draw.
                if let Some(cell) = cell {
                    pixmap.fill_rect(cell, &paint, Transform::identity(), None);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covers_the_characters_of_labels_and_names() {
        let needed = "0123456789.-+e%:/_ abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ";
        for c in needed.chars() {
            assert_ne!(glyph(c).0, MISSING, "no glyph for {c:?}");
        }
        assert_eq!(glyph('~'), (MISSING, 0));
        assert_eq!(glyph('g').1, DESCENT);
    }

    #[test]
    fn glyphs_are_distinct_and_fit_five_columns() {
        let all: Vec<_> = GLYPHS.iter().chain(DESCENDERS).collect();
        for (i, (a, rows)) in all.iter().enumerate() {
            assert!(rows.iter().all(|r| *r < 1 << GLYPH_W), "{a:?} is too wide");
            for (b, other) in &all[i + 1..] {
                assert!(a != b, "{a:?} twice");
                // 'O' and '0' differ; only the space may be blank.
                assert!(rows != other, "{a:?} and {b:?} look the same");
            }
        }
    }

    #[test]
    fn draws_the_cells_of_a_glyph() {
        let mut pixmap = Pixmap::new(20, 20).unwrap();
        pixmap.fill(Color::WHITE);
        draw_text(&mut pixmap, "-", 2.0, 3.0, 2, Color::BLACK);
        let dark = |x: u32, y: u32| pixmap.pixel(x, y).unwrap().red() == 0;
        // '-' is row 3 (pixels 3 + 6..8), columns 0..5 (pixels 2..12).
        assert!(dark(2, 9) && dark(11, 10));
        assert!(!dark(12, 9) && !dark(2, 8) && !dark(2, 11));
        assert_eq!(text_width("-1", 2), 22);
        assert_eq!(text_height(3), 21);
    }
}
