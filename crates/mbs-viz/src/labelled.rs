//! Sheets that explain themselves: each picture under a short caption,
//! and keys to the colours below the pictures (a colour bar of the
//! disparity scale, colour swatches with their meaning).

use image::{GenericImage, Rgb};
use mbs_core::RgbImage;

use crate::VizError;
use crate::chart::format_tick;
use crate::colormap::turbo;
use crate::text::{draw_text, line_height, text_width, widest_word, wrap};

/// Colour of everything on a sheet that is not a picture or text.
const BACKGROUND: [u8; 3] = [255, 255, 255];
/// Colour of text and tick marks.
const INK: [u8; 3] = [25, 25, 25];
/// Outline of a swatch, so that light colours show on the background.
const OUTLINE: [u8; 3] = [110, 110, 110];
/// Colour of invalid pixels in [`crate::colorize_disparity`].
const INVALID: [u8; 3] = [0, 0, 0];
/// Smallest text size in pixels (panels up to about 340 pixels wide).
const MIN_TEXT: f64 = 14.0;
/// Largest text size in pixels, reached by panels 864 pixels wide.
const MAX_TEXT: f64 = 36.0;
/// Shortest length of a disparity colour bar, in text sizes.
const BAR_LENGTH: f64 = 12.0;
/// Length of a disparity colour bar, in widths of the panels: it grows
/// with wide sheets.
const BAR_SHARE: u32 = 5;

/// One picture of a labelled sheet and the caption above it.
#[derive(Debug, Clone, Copy)]
pub struct Panel<'a> {
    /// The picture, copied into the sheet unchanged.
    pub image: &'a RgbImage,
    /// A short caption, e.g. "teacher disparity (px)". It is broken into
    /// lines at spaces where the picture is narrower than the text.
    pub caption: &'a str,
}

impl<'a> Panel<'a> {
    /// `image` under `caption`.
    pub const fn new(image: &'a RgbImage, caption: &'a str) -> Self {
        Self { image, caption }
    }
}

/// A key to the colours of a sheet, drawn below its pictures.
#[derive(Debug, Clone, PartialEq)]
pub enum Key {
    /// The colour scale of [`crate::colorize_disparity`] with top `max`
    /// (finite and above 0): a colour bar from 0 to `max`, tick labels at
    /// round values and at `max`, and a black swatch for pixels without a
    /// value, under `title` (which should name the unit).
    DisparityBar {
        /// Heading, e.g. "disparity (px)".
        title: String,
        /// The value drawn in the colour at the top of the scale.
        max: f32,
    },
    /// Colour swatches, one a line, each beside what its colour means.
    Swatches {
        /// Heading, e.g. "weight map".
        title: String,
        /// A colour and its meaning.
        entries: Vec<([u8; 3], String)>,
    },
}

/// Sizes of the text and spacing of a sheet.
#[derive(Debug, Clone, Copy)]
struct Metrics {
    /// Text size in pixels.
    size: f64,
    /// Height of a line of text.
    line: u32,
    /// Space around captions and keys, and between columns.
    pad: u32,
    /// Length of a disparity colour bar.
    bar: u32,
}

impl Metrics {
    /// Text a 24th of the widest panel high, from `MIN_TEXT` to `MAX_TEXT`.
    fn for_width(widest_panel: u32) -> Self {
        let size = (f64::from(widest_panel) / 24.0)
            .round()
            .clamp(MIN_TEXT, MAX_TEXT);
        Self {
            size,
            line: line_height(size),
            pad: (0.4 * size).round() as u32,
            bar: (BAR_LENGTH * size).round() as u32,
        }
    }
}

/// `panels` left to right, each under its caption, and `keys` below them;
/// [`labelled_grid`] with one row.
pub fn labelled_row(panels: &[Panel<'_>], keys: &[Key]) -> Result<RgbImage, VizError> {
    labelled_grid(&[panels], keys)
}

/// A sheet of `rows` of panels, each picture under a strip with its
/// caption, and `keys` to the colours below the last row, on white.
///
/// Text is drawn in the charts' font, a 24th of the widest panel high
/// (14 to 36 pixels). Column `c` is as wide as the widest `c`-th panel of
/// any row, or as the widest word of their captions where that is wider
/// (tiny panels get readable captions); columns are 0.4 text sizes
/// apart, and each panel is centred in its column with the pixels of
/// its picture copied unchanged. A caption wider than its column is broken
/// into lines at spaces; a row's caption strip is as high as its longest
/// caption, and its panels are aligned at the top. Keys go left to right
/// below the panels, on as many lines as the sheet's width needs; the sheet
/// is widened where a single key is wider than the panels. A colour bar is
/// a fifth of the panels' width long, and at least 12 text sizes.
///
/// It is an error if there is no panel, or a key cannot be drawn (a colour
/// bar with a top that is not a finite value above 0).
pub fn labelled_grid(rows: &[&[Panel<'_>]], keys: &[Key]) -> Result<RgbImage, VizError> {
    let Some(widest) = rows
        .iter()
        .flat_map(|row| row.iter())
        .map(|p| p.image.width())
        .max()
    else {
        return Err(VizError::Input("no panels to put on a sheet".into()));
    };
    let m = Metrics::for_width(widest);
    let grid = Grid::lay_out(rows, &m)?;
    let m = Metrics {
        bar: m.bar.max(grid.width / BAR_SHARE),
        ..m
    };
    let blocks = keys
        .iter()
        .map(|key| key.render(&m))
        .collect::<Result<Vec<_>, _>>()?;
    let widest_block = blocks.iter().map(|b| b.width()).max().unwrap_or(0);
    let width = grid.width.max(widest_block + 2 * m.pad);
    let (places, keys_height) = place_blocks(&blocks, width, &m);
    let height = grid.height + keys_height;

    let mut sheet = RgbImage::from_pixel(width, height, Rgb(BACKGROUND));
    grid.draw(&mut sheet, rows, &m)?;
    for (block, (x, y)) in blocks.iter().zip(places) {
        copy(&mut sheet, block, x, grid.height + y)?;
    }
    Ok(sheet)
}

/// Where the panels of a sheet and their captions go.
struct Grid {
    /// Left edge of each column.
    column_x: Vec<u32>,
    /// Width of each column.
    column_width: Vec<u32>,
    /// Per row, per panel: its caption broken into lines.
    captions: Vec<Vec<Vec<String>>>,
    /// Height of each row's caption strip.
    strips: Vec<u32>,
    /// Width of the panels and the spaces between their columns.
    width: u32,
    /// Height of the rows, caption strips included.
    height: u32,
}

impl Grid {
    /// The columns, captions and strips of `rows` in text of `m`'s size
    /// (see [`labelled_grid`] for the rules).
    fn lay_out(rows: &[&[Panel<'_>]], m: &Metrics) -> Result<Grid, VizError> {
        let columns = rows.iter().map(|row| row.len()).max().unwrap_or(0);
        let mut column_width = vec![0u32; columns];
        for row in rows {
            for (width, panel) in column_width.iter_mut().zip(row.iter()) {
                let word = widest_word(panel.caption, m.size)? + 2 * m.pad;
                *width = (*width).max(panel.image.width()).max(word);
            }
        }
        let column_x: Vec<u32> = column_width
            .iter()
            .scan(0, |x, w| {
                let left = *x;
                *x += w + m.pad;
                Some(left)
            })
            .collect();
        let width = column_width.iter().sum::<u32>() + m.pad * (columns as u32 - 1);
        let captions = rows
            .iter()
            .map(|row| {
                row.iter()
                    .zip(&column_width)
                    .map(|(panel, width)| wrap(panel.caption, width - 2 * m.pad, m.size))
                    .collect::<Result<Vec<_>, _>>()
            })
            .collect::<Result<Vec<_>, _>>()?;
        let strips: Vec<u32> = captions
            .iter()
            .map(|row| {
                let lines = row.iter().map(Vec::len).max().unwrap_or(0).max(1);
                m.pad + lines as u32 * m.line + m.pad / 2
            })
            .collect();
        let height = rows
            .iter()
            .zip(&strips)
            .map(|(row, strip)| strip + row_height(row))
            .sum();
        Ok(Grid {
            column_x,
            column_width,
            captions,
            strips,
            width,
            height,
        })
    }

    /// Draws `rows` (the panels laid out) and their captions into the top
    /// of `sheet`.
    fn draw(
        &self,
        sheet: &mut RgbImage,
        rows: &[&[Panel<'_>]],
        m: &Metrics,
    ) -> Result<(), VizError> {
        let mut top = 0;
        for ((row, lines), strip) in rows.iter().zip(&self.captions).zip(&self.strips) {
            for (c, (panel, lines)) in row.iter().zip(lines).enumerate() {
                let (x, column) = (self.column_x[c], self.column_width[c]);
                // Captions sit on the panel: the last line just above it.
                let first = top + strip - m.pad / 2 - lines.len() as u32 * m.line;
                for (i, line) in lines.iter().enumerate() {
                    let left = x + column.saturating_sub(text_width(line, m.size)?) / 2;
                    let line_top = first + i as u32 * m.line;
                    draw_text(sheet, line, (left as i32, line_top as i32), m.size, INK)?;
                }
                let left = x + (column - panel.image.width()) / 2;
                copy(sheet, panel.image, left, top + strip)?;
            }
            top += strip + row_height(row);
        }
        Ok(())
    }
}

/// Height of a row's tallest panel.
fn row_height(row: &[Panel<'_>]) -> u32 {
    row.iter().map(|p| p.image.height()).max().unwrap_or(0)
}

/// Copies `tile` into `sheet` with its top left corner at `(x, y)`.
fn copy(sheet: &mut RgbImage, tile: &RgbImage, x: u32, y: u32) -> Result<(), VizError> {
    sheet
        .copy_from(tile, x, y)
        .map_err(|e| VizError::Draw(e.to_string()))
}

/// Where the key blocks go below the panels of a sheet `width` wide:
/// their corners relative to the bottom of the panels, left to right on
/// lines a padding apart, and the height they take.
fn place_blocks(blocks: &[RgbImage], width: u32, m: &Metrics) -> (Vec<(u32, u32)>, u32) {
    if blocks.is_empty() {
        return (Vec::new(), 0);
    }
    let gap = (2.0 * m.size).round() as u32;
    let (mut x, mut y, mut line) = (m.pad, m.pad, 0);
    let mut places = Vec::with_capacity(blocks.len());
    for block in blocks {
        if x > m.pad && x + block.width() + m.pad > width {
            (x, y, line) = (m.pad, y + line + m.pad, 0);
        }
        places.push((x, y));
        x += block.width() + gap;
        line = line.max(block.height());
    }
    (places, y + line + m.pad)
}

/// Fills the rectangle at `(x, y)` of `width` by `height` with `colour`.
fn fill(image: &mut RgbImage, (x, y): (u32, u32), (width, height): (u32, u32), colour: [u8; 3]) {
    for row in y..(y + height).min(image.height()) {
        for column in x..(x + width).min(image.width()) {
            image.put_pixel(column, row, Rgb(colour));
        }
    }
}

/// Where the parts of a disparity colour bar lie in its key block.
#[derive(Debug, Clone, PartialEq)]
struct BarLayout {
    /// Column of the bar's first pixel (the colour of 0).
    left: u32,
    /// Row of the bar's top.
    top: u32,
    /// Length of the bar in pixels.
    length: u32,
    /// Height of the bar in pixels.
    height: u32,
    /// Values with a tick and a label, in order; the last is the top.
    ticks: Vec<f64>,
    /// Column of the black swatch for pixels without a value.
    invalid: u32,
    /// Size of the whole block.
    size: (u32, u32),
}

impl BarLayout {
    /// The column of the bar that shows `value` of a scale up to `max`.
    fn column(&self, value: f64, max: f64) -> u32 {
        self.left + ((value / max) * f64::from(self.length - 1)).round() as u32
    }
}

/// Round values from 0 up to below `max`, about four steps of 1, 2 or 5
/// times a power of ten apart.
fn round_ticks(max: f64) -> Vec<f64> {
    let raw = max / 4.0;
    let magnitude = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|k| k * magnitude)
        .find(|step| *step >= raw * 0.999)
        .unwrap_or(10.0 * magnitude);
    (0..)
        .map(|k| f64::from(k) * step)
        .take_while(|v| *v < max * (1.0 - 1e-6))
        .collect()
}

/// The label of a colour bar's black swatch.
const NO_VALUE: &str = "no value";

/// The layout of a disparity colour bar up to `max` at `m`, headed
/// `title`: round ticks whose labels would touch the top's are left out.
fn bar_layout(title: &str, max: f64, m: &Metrics) -> Result<BarLayout, VizError> {
    let length = m.bar;
    let height = m.size.round() as u32;
    let left = text_width("0", m.size)? / 2 + 1;
    let top = m.line;
    let mut layout = BarLayout {
        left,
        top,
        length,
        height,
        ticks: Vec::new(),
        invalid: 0,
        size: (0, 0),
    };
    let top_label = text_width(&format_tick(max), m.size)?;
    let top_column = layout.column(max, max);
    let mut ticks = Vec::new();
    for value in round_ticks(max) {
        let label = text_width(&format_tick(value), m.size)?;
        let room = (label + top_label) / 2 + m.size.round() as u32;
        if layout.column(value, max) + room <= top_column {
            ticks.push(value);
        }
    }
    ticks.push(max);
    layout.ticks = ticks;
    let right = (left + length).max(top_column + top_label / 2 + 1);
    layout.invalid = right + 2 * m.pad;
    let width = (layout.invalid + height + m.pad + text_width(NO_VALUE, m.size)?)
        .max(text_width(title, m.size)?);
    let tick = tick_length(m);
    layout.size = (width, top + height + tick + m.line);
    Ok(layout)
}

/// Length of the tick marks under a colour bar.
fn tick_length(m: &Metrics) -> u32 {
    (0.3 * m.size).round() as u32
}

/// Width of a tick mark.
fn tick_width(m: &Metrics) -> u32 {
    (m.size / 14.0).round().max(1.0) as u32
}

impl Key {
    /// The key drawn on white at the text size of `m`.
    fn render(&self, m: &Metrics) -> Result<RgbImage, VizError> {
        match self {
            Key::DisparityBar { title, max } => render_bar(title, *max, m),
            Key::Swatches { title, entries } => render_swatches(title, entries, m),
        }
    }
}

/// A disparity colour bar key (see [`Key::DisparityBar`]).
fn render_bar(title: &str, max: f32, m: &Metrics) -> Result<RgbImage, VizError> {
    if !(max.is_finite() && max > 0.0) {
        return Err(VizError::Input(format!(
            "the colour bar of {title:?} needs a top above 0, not {max}"
        )));
    }
    let max = f64::from(max);
    let layout = bar_layout(title, max, m)?;
    let (width, height) = layout.size;
    let mut block = RgbImage::from_pixel(width, height, Rgb(BACKGROUND));
    draw_text(&mut block, title, (0, 0), m.size, INK)?;
    for i in 0..layout.length {
        let colour = turbo(i as f32 / (layout.length - 1) as f32);
        fill(
            &mut block,
            (layout.left + i, layout.top),
            (1, layout.height),
            colour,
        );
    }
    let below = layout.top + layout.height;
    let (tick, thick) = (tick_length(m), tick_width(m));
    for &value in &layout.ticks {
        let x = layout.column(value, max);
        fill(&mut block, (x - thick / 2, below), (thick, tick), INK);
        let label = format_tick(value);
        let left = x as i32 - (text_width(&label, m.size)? / 2) as i32;
        draw_text(
            &mut block,
            &label,
            (left, (below + tick) as i32),
            m.size,
            INK,
        )?;
    }
    let side = layout.height;
    fill(
        &mut block,
        (layout.invalid, layout.top),
        (side, side),
        INVALID,
    );
    let text_top = layout.top as i32 + (side as i32 - m.line as i32) / 2;
    let text_left = (layout.invalid + side + m.pad) as i32;
    draw_text(&mut block, NO_VALUE, (text_left, text_top), m.size, INK)?;
    Ok(block)
}

/// Side of a colour swatch at `m`.
fn swatch_side(m: &Metrics) -> u32 {
    (0.8 * m.size).round() as u32
}

/// A key of colour swatches (see [`Key::Swatches`]).
fn render_swatches(
    title: &str,
    entries: &[([u8; 3], String)],
    m: &Metrics,
) -> Result<RgbImage, VizError> {
    let side = swatch_side(m);
    let mut width = text_width(title, m.size)?;
    for (_, meaning) in entries {
        width = width.max(side + m.pad + text_width(meaning, m.size)?);
    }
    let height = m.line * (entries.len() as u32 + 1);
    let mut block = RgbImage::from_pixel(width, height, Rgb(BACKGROUND));
    draw_text(&mut block, title, (0, 0), m.size, INK)?;
    for (i, (colour, meaning)) in entries.iter().enumerate() {
        let line_top = m.line * (i as u32 + 1);
        let y = line_top + (m.line - side) / 2;
        fill(&mut block, (0, y), (side, side), OUTLINE);
        fill(&mut block, (1, y + 1), (side - 2, side - 2), *colour);
        let left = (side + m.pad) as i32;
        draw_text(&mut block, meaning, (left, line_top as i32), m.size, INK)?;
    }
    Ok(block)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colorize_disparity;
    use mbs_core::FloatImage;

    /// A picture whose every pixel differs from its neighbours.
    fn picture(width: u32, height: u32, seed: u8) -> RgbImage {
        RgbImage::from_fn(width, height, |x, y| {
            Rgb([
                (x * 7 + y) as u8 ^ seed,
                (y * 13 + x * 3) as u8,
                seed.wrapping_add((x + y) as u8),
            ])
        })
    }

    /// Pixels darker than 110 in every channel (text) in the rectangle.
    fn dark(image: &RgbImage, (x, y): (u32, u32), (w, h): (u32, u32)) -> usize {
        (y..y + h)
            .flat_map(|y| (x..x + w).map(move |x| (x, y)))
            .filter(|&(x, y)| image.get_pixel(x, y).0.iter().all(|&c| c < 110))
            .count()
    }

    /// Whether `tile` lies unchanged in `sheet` with its corner at `(x, y)`.
    fn holds(sheet: &RgbImage, tile: &RgbImage, (x, y): (u32, u32)) -> bool {
        tile.enumerate_pixels()
            .all(|(i, j, p)| sheet.get_pixel(x + i, y + j) == p)
    }

    #[test]
    fn sheet_is_the_panels_under_their_caption_strips() {
        let (a, b) = (picture(200, 50, 1), picture(300, 60, 2));
        let sheet = labelled_row(&[Panel::new(&a, "left"), Panel::new(&b, "right")], &[]).unwrap();
        let m = Metrics::for_width(300);
        assert_eq!(m.size, MIN_TEXT);
        let strip = m.pad + m.line + m.pad / 2;
        assert_eq!(sheet.dimensions(), (200 + m.pad + 300, strip + 60));
        assert!(holds(&sheet, &a, (0, strip)));
        assert!(holds(&sheet, &b, (200 + m.pad, strip)));
        // Text in each strip, white between the panels and below the
        // shorter one.
        assert!(dark(&sheet, (0, 0), (200, strip)) > 30);
        assert!(dark(&sheet, (200 + m.pad, 0), (300, strip)) > 30);
        for y in 0..sheet.height() {
            for x in 200..200 + m.pad {
                assert_eq!(sheet.get_pixel(x, y).0, BACKGROUND, "gap at {x},{y}");
            }
        }
        assert_eq!(sheet.get_pixel(100, strip + 55).0, BACKGROUND);
        // Nothing to draw is an error.
        assert!(labelled_row(&[], &[]).is_err());
        assert!(labelled_grid(&[&[], &[]], &[]).is_err());
    }

    #[test]
    fn grids_align_columns_and_wrap_long_captions() {
        let tiles: Vec<RgbImage> = (0..4).map(|i| picture(160, 64, i)).collect();
        let top = [Panel::new(&tiles[0], "a"), Panel::new(&tiles[1], "b")];
        let long = "image_1: synthesised pixels (red) of the new view";
        let bottom = [Panel::new(&tiles[2], long), Panel::new(&tiles[3], "d")];
        let sheet = labelled_grid(&[&top, &bottom], &[]).unwrap();
        let m = Metrics::for_width(160);
        let lines = wrap(long, 160 - 2 * m.pad, m.size).unwrap().len() as u32;
        assert!(lines >= 3, "{lines} lines");
        let (strip_1, strip_2) = (
            m.pad + m.line + m.pad / 2,
            m.pad + lines * m.line + m.pad / 2,
        );
        assert_eq!(
            sheet.dimensions(),
            (2 * 160 + m.pad, strip_1 + 64 + strip_2 + 64)
        );
        let second = strip_1 + 64 + strip_2;
        assert!(holds(&sheet, &tiles[0], (0, strip_1)));
        assert!(holds(&sheet, &tiles[1], (160 + m.pad, strip_1)));
        assert!(holds(&sheet, &tiles[2], (0, second)));
        assert!(holds(&sheet, &tiles[3], (160 + m.pad, second)));
        // Every line of the long caption has text; the short caption's
        // strip is blank above its one line.
        for i in 0..lines {
            let y = strip_1 + 64 + m.pad + i * m.line;
            assert!(dark(&sheet, (0, y), (160, m.line)) > 20, "line {i}");
        }
        assert_eq!(dark(&sheet, (160 + m.pad, strip_1 + 64), (160, m.line)), 0);
        assert!(dark(&sheet, (160 + m.pad, second - m.line), (160, m.line)) > 5);
    }

    #[test]
    fn tiny_panels_get_columns_wide_enough_for_their_words() {
        let dot = picture(1, 1, 9);
        let thin = picture(3, 40, 4);
        let keys = [
            Key::DisparityBar {
                title: "disparity (px)".into(),
                max: 2.0,
            },
            Key::Swatches {
                title: "masks".into(),
                entries: vec![([255, 255, 255], "white".into())],
            },
        ];
        let sheet = labelled_row(
            &[Panel::new(&dot, "reference"), Panel::new(&thin, "")],
            &keys,
        )
        .unwrap();
        let m = Metrics::for_width(3);
        let column = text_width("reference", m.size).unwrap() + 2 * m.pad;
        let bar = bar_layout("disparity (px)", 2.0, &m).unwrap();
        assert!(sheet.width() >= bar.size.0 + 2 * m.pad);
        let strip = m.pad + m.line + m.pad / 2;
        assert!(holds(&sheet, &dot, ((column - 1) / 2, strip)));
        let thin_left = column + m.pad + (2 * m.pad - 3) / 2;
        assert!(holds(&sheet, &thin, (thin_left, strip)));
        assert!(dark(&sheet, (0, 0), (column, strip)) > 30);
        // The two keys are below the panels, one above the other when the
        // sheet is narrower than both side by side.
        let below = strip + 40;
        assert!(dark(&sheet, (0, below), (sheet.width(), sheet.height() - below)) > 100);
        // Every size from 1x1 up works, without or with a caption.
        for (w, h) in [(1, 1), (1, 7), (7, 1), (64, 160), (160, 64)] {
            let tile = picture(w, h, 3);
            for caption in ["", "x", "a long caption for a tiny panel"] {
                let sheet = labelled_row(&[Panel::new(&tile, caption)], &keys).unwrap();
                assert!(sheet.width() >= w && sheet.height() > h);
            }
        }
    }

    #[test]
    fn the_colour_bar_runs_through_the_colour_map_from_0_to_max() {
        let m = Metrics::for_width(384);
        let max = 63.7f32;
        let layout = bar_layout("disparity (px)", f64::from(max), &m).unwrap();
        let block = render_bar("disparity (px)", max, &m).unwrap();
        assert_eq!(block.dimensions(), layout.size);
        let ends = FloatImage::from_raw(2, 1, vec![0.0, max]).unwrap();
        let ends = colorize_disparity(&ends, max);
        let mid = layout.top + layout.height / 2;
        let (first, last) = (layout.left, layout.left + layout.length - 1);
        assert_eq!(block.get_pixel(first, mid), ends.get_pixel(0, 0));
        assert_eq!(block.get_pixel(last, mid), ends.get_pixel(1, 0));
        assert_eq!(block.get_pixel(first - 1, mid).0, BACKGROUND);
        assert_eq!(block.get_pixel(last + 1, mid).0, BACKGROUND);
        // Every column between has the map's colour at its value.
        for i in 0..layout.length {
            let t = i as f32 / (layout.length - 1) as f32;
            assert_eq!(block.get_pixel(first + i, layout.top).0, turbo(t));
        }
        // Ticks at 0, 20, 40 and the top; 60 would touch the top's label.
        assert_eq!(layout.ticks, [0.0, 20.0, 40.0, f64::from(max)]);
        let below = layout.top + layout.height;
        for &v in &layout.ticks {
            let x = layout.column(v, f64::from(max));
            assert_eq!(block.get_pixel(x, below).0, INK, "tick at {v}");
            assert!(
                dark(&block, (x - 4, below + 2), (9, m.line)) > 3,
                "label of {v}"
            );
        }
        // The black swatch for pixels without a value, and the heading.
        assert_eq!(block.get_pixel(layout.invalid + 2, mid).0, INVALID);
        assert!(dark(&block, (0, 0), (layout.length, m.line)) > 50);

        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let err = render_bar("d", bad, &m).unwrap_err();
            assert!(err.to_string().contains("above 0"), "{err}");
        }
    }

    #[test]
    fn round_ticks_step_by_one_two_or_five() {
        assert_eq!(round_ticks(192.0), [0.0, 50.0, 100.0, 150.0]);
        assert_eq!(round_ticks(100.0), [0.0, 50.0]);
        assert_eq!(round_ticks(1.0), [0.0, 0.5]);
        assert_eq!(round_ticks(16.0), [0.0, 5.0, 10.0, 15.0]);
        assert_eq!(round_ticks(0.3).len(), 3);
    }

    #[test]
    fn swatches_show_each_colour_beside_its_meaning() {
        let m = Metrics::for_width(100);
        let entries = vec![
            ([230, 40, 40], "weight 0".to_string()),
            ([40, 210, 60], "weight ω".to_string()),
        ];
        let block = render_swatches("weight map", &entries, &m).unwrap();
        assert_eq!(block.height(), 3 * m.line);
        let side = swatch_side(&m);
        for (i, (colour, _)) in entries.iter().enumerate() {
            let top = m.line * (i as u32 + 1);
            let centre = top + m.line / 2;
            assert_eq!(block.get_pixel(side / 2, centre).0, *colour);
            let text = (side + m.pad, top);
            assert!(dark(&block, text, (block.width() - text.0, m.line)) > 20);
        }
    }
}
