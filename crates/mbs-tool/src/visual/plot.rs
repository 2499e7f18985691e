//! Loss curves as a PNG: one anti-aliased line per series over training
//! steps, with grid, tick labels, legend and title, drawn with tiny-skia.

use std::path::Path;

use anyhow::{Context, bail};
use tiny_skia::{
    Color, FillRule, LineCap, LineJoin, Mask, Paint, PathBuilder, Pixmap, Rect, Stroke, Transform,
};

use super::axis::{Axis, TARGET_TICKS};
use super::font::{draw_text, text_height, text_width};

/// Canvas width in pixels.
const WIDTH: u32 = 800;
/// Canvas height in pixels.
const HEIGHT: u32 = 480;
/// Font scale of the title.
const TITLE_SCALE: u32 = 3;
/// Font scale of tick labels, the axis name and the legend.
const LABEL_SCALE: u32 = 2;
/// Width of a series' line in pixels.
const LINE_WIDTH: f32 = 2.0;
/// Legend entries longer than this many characters are shortened.
const MAX_NAME_CHARS: usize = 40;

/// Series colours, in order (Matplotlib's "tab10"); more series reuse them.
const PALETTE: [[u8; 3]; 10] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
];
/// Colour of all text.
const TEXT: [u8; 3] = [40, 40, 40];
/// Colour of the plot frame and the tick marks.
const FRAME: [u8; 3] = [60, 60, 60];
/// Colour of the grid lines.
const GRID: [u8; 3] = [225, 225, 225];
/// Colour of the legend's border.
const LEGEND_FRAME: [u8; 3] = [180, 180, 180];

/// One curve of a plot.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Series {
    /// Shown in the legend.
    pub name: String,
    /// (x, y) points in drawing order: x the training step, y the value.
    pub points: Vec<(f64, f64)>,
}

/// The colour of the `index`-th series of a plot.
fn series_color(index: usize) -> [u8; 3] {
    PALETTE[index % PALETTE.len()]
}

/// An opaque tiny-skia colour.
fn color([r, g, b]: [u8; 3]) -> Color {
    Color::from_rgba8(r, g, b, 255)
}

/// An anti-aliased paint of one opaque colour.
fn solid(rgb: [u8; 3]) -> Paint<'static> {
    let mut paint = Paint::default();
    paint.set_color(color(rgb));
    paint
}

/// Draws `series` (x = step, y = value) into an 800x480 PNG at `path`,
/// written atomically, with `title` on top and a legend naming each series.
/// With `log_y` the value axis is logarithmic, with decade ticks.
///
/// Points with a non-finite coordinate are skipped (the line joins their
/// neighbours), and so are values <= 0 on a log axis. It is an error if
/// `series` is empty or no series has a point left to draw.
pub(crate) fn write_loss_plot(
    path: &Path,
    title: &str,
    series: &[Series],
    log_y: bool,
) -> anyhow::Result<()> {
    let (pixmap, _) = render(title, series, log_y)
        .with_context(|| format!("cannot draw the plot {}", path.display()))?;
    let png = pixmap
        .encode_png()
        .with_context(|| format!("cannot encode the plot {} as PNG", path.display()))?;
    mbs_core::atomic::write_bytes_atomic(path, &png)?;
    Ok(())
}

/// The points of `series` that can be drawn.
fn drawable(series: &Series, log_y: bool) -> Vec<(f64, f64)> {
    series
        .points
        .iter()
        .copied()
        .filter(|&(x, y)| x.is_finite() && y.is_finite() && (!log_y || y > 0.0))
        .collect()
}

/// Where the parts of the picture went, in pixels (the tests check the
/// drawing against it).
#[derive(Debug)]
#[cfg_attr(not(test), allow(dead_code))]
struct Layout {
    /// The plot area, inside the frame.
    plot: Rect,
    /// The legend box (none if it could not be placed).
    legend: Option<Rect>,
}

/// Draws the whole picture.
fn render(title: &str, series: &[Series], log_y: bool) -> anyhow::Result<(Pixmap, Layout)> {
    if series.is_empty() {
        bail!("no series to plot");
    }
    let curves: Vec<Vec<(f64, f64)>> = series.iter().map(|s| drawable(s, log_y)).collect();
    let all = || curves.iter().flatten();
    let Some(&(x0, y0)) = all().next() else {
        let what = if log_y { "finite positive" } else { "finite" };
        bail!("no {what} point to plot in {} series", series.len());
    };
    let (mut x_min, mut x_max, mut y_min, mut y_max) = (x0, x0, y0, y0);
    for &(x, y) in all() {
        (x_min, x_max) = (x_min.min(x), x_max.max(x));
        (y_min, y_max) = (y_min.min(y), y_max.max(y));
    }
    let y_axis = if log_y {
        Axis::log10(y_min, y_max, 0.04)
    } else {
        Axis::linear(y_min, y_max, 0.04, TARGET_TICKS)?
    };

    // Pixmap::new fails only for a zero or gigantic size.
    let mut pixmap = Pixmap::new(WIDTH, HEIGHT).context("cannot allocate the canvas")?;
    pixmap.fill(Color::WHITE);

    let y_label_width = y_axis
        .ticks
        .iter()
        .map(|t| text_width(&t.label, LABEL_SCALE))
        .max()
        .unwrap_or(0);
    let left = (y_label_width + 18).max(40) as f32;
    let plot = Rect::from_ltrb(left, 46.0, WIDTH as f32 - 24.0, HEIGHT as f32 - 58.0)
        .context("the tick labels leave no room for the plot")?;
    let x_axis = x_axis_fitting(x_min, x_max, plot.width())?;
    let to_px = |x: f64, y: f64| {
        (
            plot.left() + (x_axis.fraction(x) as f32) * plot.width(),
            plot.bottom() - (y_axis.fraction(y) as f32) * plot.height(),
        )
    };

    draw_grid_and_ticks(&mut pixmap, &plot, &x_axis, &y_axis);
    // Curves are clipped to the plot area. Mask::new fails only for a zero
    // size; the curves then go unclipped, and the axes keep them inside anyway.
    let clip = Mask::new(WIDTH, HEIGHT).map(|mut mask| {
        let area = PathBuilder::from_rect(plot);
        mask.fill_path(&area, FillRule::Winding, false, Transform::identity());
        mask
    });
    let mut drawn = Vec::new();
    for (i, curve) in curves.iter().enumerate() {
        let points: Vec<(f32, f32)> = curve.iter().map(|&(x, y)| to_px(x, y)).collect();
        let points = decimate(&points);
        draw_curve(&mut pixmap, clip.as_ref(), &points, series_color(i));
        drawn.extend(points);
    }
    draw_frame(&mut pixmap, &plot);
    draw_title(&mut pixmap, title);
    let names: Vec<&str> = series.iter().map(|s| s.name.as_str()).collect();
    let legend = legend_box(&plot, &names, &drawn);
    if let Some(legend) = legend {
        draw_legend(&mut pixmap, &legend, &names);
    }
    Ok((pixmap, Layout { plot, legend }))
}

/// A linear x axis over `[min, max]` whose tick labels fit side by side in
/// `width` pixels: as many ticks as fit, up to about [`TARGET_TICKS`].
fn x_axis_fitting(min: f64, max: f64, width: f32) -> anyhow::Result<Axis> {
    let fits = |axis: &Axis| {
        axis.ticks.windows(2).all(|pair| {
            let gap = (axis.fraction(pair[1].value) - axis.fraction(pair[0].value)) as f32 * width;
            let half_widths = (text_width(&pair[0].label, LABEL_SCALE)
                + text_width(&pair[1].label, LABEL_SCALE)) as f32
                / 2.0;
            gap >= half_widths + 16.0
        })
    };
    let mut axis = Axis::linear(min, max, 0.0, TARGET_TICKS)?;
    for target in [4.0, 3.0, 2.0, 1.0] {
        if fits(&axis) {
            break;
        }
        axis = Axis::linear(min, max, 0.0, target)?;
    }
    Ok(axis)
}

/// A filled axis-aligned rectangle (nothing for an empty one).
fn fill(pixmap: &mut Pixmap, l: f32, t: f32, r: f32, b: f32, paint: &Paint) {
    if let Some(rect) = Rect::from_ltrb(l, t, r, b) {
        pixmap.fill_rect(rect, paint, Transform::identity(), None);
    }
}

/// Light grid lines at the ticks, tick marks outside the frame, and their labels.
fn draw_grid_and_ticks(pixmap: &mut Pixmap, plot: &Rect, x_axis: &Axis, y_axis: &Axis) {
    let grid = solid(GRID);
    let frame = solid(FRAME);
    let text = color(TEXT);
    let label_h = text_height(LABEL_SCALE) as f32;
    // Whole pixels keep one-pixel lines crisp.
    let mut last_label_end = f32::NEG_INFINITY;
    for tick in &x_axis.ticks {
        let x = (plot.left() + x_axis.fraction(tick.value) as f32 * plot.width()).round();
        fill(pixmap, x, plot.top(), x + 1.0, plot.bottom(), &grid);
        fill(
            pixmap,
            x,
            plot.bottom(),
            x + 1.0,
            plot.bottom() + 5.0,
            &frame,
        );
        let w = text_width(&tick.label, LABEL_SCALE) as f32;
        // Not `clamp`: it panics for a label wider than the canvas.
        let start = (x - w / 2.0).min(WIDTH as f32 - w).max(0.0);
        // Labels that would still overlap the previous one are left out.
        if start > last_label_end + 8.0 {
            draw_text(
                pixmap,
                &tick.label,
                start,
                plot.bottom() + 9.0,
                LABEL_SCALE,
                text,
            );
            last_label_end = start + w;
        }
    }
    for tick in &y_axis.ticks {
        let y = (plot.bottom() - y_axis.fraction(tick.value) as f32 * plot.height()).round();
        fill(pixmap, plot.left(), y, plot.right(), y + 1.0, &grid);
        fill(pixmap, plot.left() - 5.0, y, plot.left(), y + 1.0, &frame);
        let w = text_width(&tick.label, LABEL_SCALE) as f32;
        let top = y - (label_h / 2.0).floor();
        draw_text(
            pixmap,
            &tick.label,
            plot.left() - 9.0 - w,
            top,
            LABEL_SCALE,
            text,
        );
    }
    let name = "step";
    let w = text_width(name, LABEL_SCALE) as f32;
    let x = plot.left() + (plot.width() - w) / 2.0;
    draw_text(pixmap, name, x, HEIGHT as f32 - 22.0, LABEL_SCALE, text);
}

/// Drops points of a polyline (in pixels) that barely change the picture,
/// so that a curve of 100k steps draws as fast as one of a few thousand: of
/// each run of consecutive points in one pixel column it keeps the first,
/// the highest, the lowest and the last, in their order.
fn decimate(points: &[(f32, f32)]) -> Vec<(f32, f32)> {
    let mut kept = Vec::with_capacity(points.len().min(4 * WIDTH as usize));
    let mut rest = points;
    while let Some(&(x, _)) = rest.first() {
        let column = x.floor();
        let len = rest
            .iter()
            .position(|p| p.0.floor() != column)
            .unwrap_or(rest.len());
        let (run, tail) = rest.split_at(len);
        if run.len() <= 4 {
            kept.extend_from_slice(run);
        } else {
            let by_y = |a: &&(f32, f32), b: &&(f32, f32)| a.1.total_cmp(&b.1);
            let (mut top, mut bottom) = (0, 0);
            for (i, p) in run.iter().enumerate() {
                if by_y(&p, &&run[top]).is_lt() {
                    top = i;
                }
                if by_y(&p, &&run[bottom]).is_gt() {
                    bottom = i;
                }
            }
            let mut keep = [0, top, bottom, run.len() - 1];
            keep.sort_unstable();
            let mut last = None;
            for i in keep {
                if last != Some(i) {
                    kept.push(run[i]);
                    last = Some(i);
                }
            }
        }
        rest = tail;
    }
    kept
}

/// One series at pixel positions `points`: an anti-aliased polyline, or a
/// dot for a single point, clipped to `clip`.
fn draw_curve(pixmap: &mut Pixmap, clip: Option<&Mask>, points: &[(f32, f32)], rgb: [u8; 3]) {
    let paint = solid(rgb);
    let path = match points {
        [] => return,
        [(x, y)] => {
            let dot = PathBuilder::from_circle(*x, *y, 2.0 * LINE_WIDTH);
            if let Some(dot) = dot {
                pixmap.fill_path(&dot, &paint, FillRule::Winding, Transform::identity(), clip);
            }
            return;
        }
        [(x, y), rest @ ..] => {
            let mut pb = PathBuilder::with_capacity(points.len(), points.len());
            pb.move_to(*x, *y);
            for (x, y) in rest {
                pb.line_to(*x, *y);
            }
            pb.finish()
        }
    };
    let stroke = Stroke {
        width: LINE_WIDTH,
        line_cap: LineCap::Round,
        line_join: LineJoin::Round,
        ..Stroke::default()
    };
    // `finish` gives no path only for a degenerate one (nothing to draw).
    if let Some(path) = path {
        pixmap.stroke_path(&path, &paint, &stroke, Transform::identity(), clip);
    }
}

/// The one-pixel frame around the plot area.
fn draw_frame(pixmap: &mut Pixmap, plot: &Rect) {
    let frame = solid(FRAME);
    let (l, t) = (plot.left().round(), plot.top().round());
    let (r, b) = (plot.right().round(), plot.bottom().round());
    fill(pixmap, l - 1.0, t - 1.0, r + 1.0, t, &frame);
    fill(pixmap, l - 1.0, b, r + 1.0, b + 1.0, &frame);
    fill(pixmap, l - 1.0, t, l, b, &frame);
    fill(pixmap, r, t, r + 1.0, b, &frame);
}

/// The title, centred on top, smaller if it is too wide.
fn draw_title(pixmap: &mut Pixmap, title: &str) {
    let scale = (1..=TITLE_SCALE)
        .rev()
        .find(|&s| text_width(title, s) + 16 <= WIDTH)
        .unwrap_or(1);
    let w = text_width(title, scale) as f32;
    let x = ((WIDTH as f32 - w) / 2.0).max(8.0);
    draw_text(pixmap, title, x, 12.0, scale, color(TEXT));
}

/// `name`, shortened to [`MAX_NAME_CHARS`] characters.
fn legend_name(name: &str) -> String {
    if name.chars().count() <= MAX_NAME_CHARS {
        name.to_string()
    } else {
        let kept: String = name.chars().take(MAX_NAME_CHARS - 3).collect();
        format!("{kept}...")
    }
}

/// Where the legend box of `names` goes: the corner of the plot where it
/// hides the fewest of the curves' `points` (pixels), top right on a tie.
fn legend_box(plot: &Rect, names: &[&str], points: &[(f32, f32)]) -> Option<Rect> {
    let name_w = names
        .iter()
        .map(|n| text_width(&legend_name(n), LABEL_SCALE))
        .max()
        .unwrap_or(0) as f32;
    let w = 8.0 + 20.0 + 8.0 + name_w + 10.0;
    let h = 6.0 + 20.0 * names.len() as f32 + 2.0;
    let (left, right) = (plot.left() + 10.0, plot.right() - 10.0 - w);
    let (top, bottom) = (plot.top() + 10.0, plot.bottom() - 10.0 - h);
    let hidden = |r: &Rect| {
        let inside = |&&(x, y): &&(f32, f32)| {
            r.left() <= x && x <= r.right() && r.top() <= y && y <= r.bottom()
        };
        points.iter().filter(inside).count()
    };
    [(right, top), (left, top), (right, bottom), (left, bottom)]
        .into_iter()
        .filter_map(|(x, y)| Rect::from_xywh(x, y, w, h))
        // The first of equals: top right wins a tie.
        .min_by_key(hidden)
}

/// The legend in box `bx`: a colour swatch and the name of each series.
fn draw_legend(pixmap: &mut Pixmap, bx: &Rect, names: &[&str]) {
    let mut background = solid([255, 255, 255]);
    background.set_color_rgba8(255, 255, 255, 230);
    pixmap.fill_rect(*bx, &background, Transform::identity(), None);
    let edge = solid(LEGEND_FRAME);
    let (l, t, r, b) = (bx.left(), bx.top(), bx.right(), bx.bottom());
    fill(pixmap, l, t, r, t + 1.0, &edge);
    fill(pixmap, l, b - 1.0, r, b, &edge);
    fill(pixmap, l, t, l + 1.0, b, &edge);
    fill(pixmap, r - 1.0, t, r, b, &edge);
    for (i, name) in names.iter().enumerate() {
        let row_top = t + 6.0 + 20.0 * i as f32;
        let swatch = solid(series_color(i));
        fill(
            pixmap,
            l + 8.0,
            row_top + 2.0,
            l + 28.0,
            row_top + 12.0,
            &swatch,
        );
        let label = legend_name(name);
        draw_text(pixmap, &label, l + 36.0, row_top, LABEL_SCALE, color(TEXT));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(name: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.to_string(),
            points,
        }
    }

    fn inside(rect: &Rect, x: u32, y: u32) -> bool {
        let (x, y) = (x as f32 + 0.5, y as f32 + 0.5);
        rect.left() <= x && x <= rect.right() && rect.top() <= y && y <= rect.bottom()
    }

    /// Writes the plot, checks the file, and returns its pixels and layout.
    fn plot(path: &Path, series: &[Series], log_y: bool) -> (image::RgbImage, Layout) {
        write_loss_plot(path, "S3 training loss", series, log_y).unwrap();
        assert!(!mbs_core::atomic::partial_path(path).exists());
        let img = image::open(path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (800, 480));
        let (_, layout) = render("S3 training loss", series, log_y).unwrap();
        (img, layout)
    }

    /// Pixels of exactly `rgb` inside the plot area but outside the legend.
    fn curve_pixels(img: &image::RgbImage, layout: &Layout, rgb: [u8; 3]) -> Vec<(u32, u32)> {
        let legend = layout.legend.unwrap();
        img.enumerate_pixels()
            .filter(|(x, y, p)| {
                p.0 == rgb && inside(&layout.plot, *x, *y) && !inside(&legend, *x, *y)
            })
            .map(|(x, y, _)| (x, y))
            .collect()
    }

    #[test]
    fn writes_an_800x480_png_with_a_line_and_a_swatch_per_series() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("plots/loss.png");
        let falling: Vec<(f64, f64)> = (0..=200)
            .map(|i| (i as f64 * 10.0, 1.0 / (1.0 + i as f64 / 20.0)))
            .collect();
        let mut noisy: Vec<(f64, f64)> = (0..=200)
            .map(|i| {
                (
                    i as f64 * 10.0,
                    0.6 - 0.001 * i as f64 + 0.05 * (i as f64).sin(),
                )
            })
            .collect();
        noisy[50].1 = f64::NAN;
        noisy[60].0 = f64::INFINITY;
        let all = [
            series("photometric", falling),
            series("distillation", noisy),
            series("EPE_1 (px): 3% / Out-3", vec![(0.0, 0.9), (2000.0, 0.3)]),
        ];
        let (img, layout) = plot(&path, &all, false);
        assert_eq!(img.get_pixel(0, 0).0, [255, 255, 255]);
        let legend = layout.legend.unwrap();
        for i in 0..all.len() {
            let n = curve_pixels(&img, &layout, series_color(i)).len();
            assert!(n > 200, "series {i}: {n} pixels of its colour");
            let swatch = img
                .enumerate_pixels()
                .filter(|(x, y, p)| p.0 == series_color(i) && inside(&legend, *x, *y))
                .count();
            assert_eq!(swatch, 20 * 10, "series {i}: swatch");
        }
        // Title, tick labels and legend names.
        let text = img.pixels().filter(|p| p.0 == TEXT).count();
        assert!(text > 1000, "{text} text pixels");
    }

    #[test]
    fn log_scale_draws_exponential_decay_straight() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("loss-log.png");
        let mut points: Vec<(f64, f64)> = (0..=100)
            .map(|i| (i as f64, 10f64.powf(-(i as f64) / 25.0)))
            .collect();
        // No logarithm: skipped.
        points.insert(30, (30.5, 0.0));
        points.insert(60, (60.5, -1.0));
        let (img, layout) = plot(&path, &[series("loss", points)], true);
        let pixels = curve_pixels(&img, &layout, series_color(0));
        assert!(pixels.len() > 300, "{} pixels", pixels.len());

        // A straight line: the curve's mean row in each column is linear in
        // the column (the skipped points would have dived to the bottom).
        let mean_row = |x: u32| {
            let ys: Vec<f32> = pixels
                .iter()
                .filter(|p| p.0 == x)
                .map(|p| p.1 as f32)
                .collect();
            ys.iter().sum::<f32>() / ys.len() as f32
        };
        let (x0, x1) = (
            layout.plot.left() as u32 + 10,
            layout.plot.right() as u32 - 10,
        );
        for x in [x0 + 100, (x0 + x1) / 2, x1 - 100] {
            let t = (x - x0) as f32 / (x1 - x0) as f32;
            let expected = mean_row(x0) + t * (mean_row(x1) - mean_row(x0));
            assert!(
                (mean_row(x) - expected).abs() < 2.0,
                "column {x}: {} vs {expected}",
                mean_row(x)
            );
        }
        // Decade ticks 1, 0.1, ..., 0.0001 are labelled in the text colour
        // left of the frame.
        let labels = img
            .enumerate_pixels()
            .filter(|(x, _, p)| p.0 == TEXT && (*x as f32) < layout.plot.left() - 5.0)
            .count();
        assert!(labels > 200, "{labels}");
    }

    #[test]
    fn no_drawable_point_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("empty.png");
        let nan = series("loss", vec![(0.0, f64::NAN), (f64::NAN, 1.0)]);
        for (all, log_y) in [
            (vec![], false),
            (vec![nan, series("none", vec![])], false),
            (vec![series("loss", vec![(0.0, 0.0), (1.0, -2.0)])], true),
        ] {
            let err = write_loss_plot(&path, "t", &all, log_y).unwrap_err();
            let msg = format!("{err:#}");
            assert!(msg.contains("empty.png"), "{msg}");
            assert!(!path.exists());
        }
    }

    #[test]
    fn a_single_point_and_a_constant_series_are_drawn() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("flat.png");
        let all = [
            series("one", vec![(5.0, 3.0)]),
            series("flat", vec![(0.0, 2.0), (10.0, 2.0)]),
        ];
        let (img, layout) = plot(&path, &all, false);
        assert!(curve_pixels(&img, &layout, series_color(0)).len() > 10);
        assert!(curve_pixels(&img, &layout, series_color(1)).len() > 200);
    }

    #[test]
    fn decimation_keeps_the_extremes_of_each_pixel_column() {
        // 1000 points in 10 columns, a saw tooth in each.
        let points: Vec<(f32, f32)> = (0..1000)
            .map(|i| (i as f32 / 100.0, ((i * 37) % 101) as f32))
            .collect();
        let kept = decimate(&points);
        assert!(kept.len() <= 40, "{}", kept.len());
        for column in 0..10 {
            let run: Vec<_> = points
                .iter()
                .filter(|p| p.0.floor() == column as f32)
                .collect();
            let ours: Vec<_> = kept
                .iter()
                .filter(|p| p.0.floor() == column as f32)
                .collect();
            let max = |v: &[&(f32, f32)]| v.iter().map(|p| p.1).fold(f32::MIN, f32::max);
            let min = |v: &[&(f32, f32)]| v.iter().map(|p| p.1).fold(f32::MAX, f32::min);
            assert_eq!(max(&run), max(&ours));
            assert_eq!(min(&run), min(&ours));
            assert_eq!(run.first(), ours.first());
            assert_eq!(run.last(), ours.last());
        }
        // Kept in their order: x never decreases.
        assert!(kept.windows(2).all(|w| w[0].0 <= w[1].0));
        // Short runs stay whole.
        let few = [(0.5, 1.0), (1.5, 2.0), (1.7, 0.0)];
        assert_eq!(decimate(&few), few);
    }

    #[test]
    fn the_legend_goes_where_it_hides_the_least() {
        let plot = Rect::from_ltrb(60.0, 46.0, 776.0, 422.0).unwrap();
        let names = ["loss"];
        let top_right = legend_box(&plot, &names, &[]).unwrap();
        assert_eq!(top_right.right(), plot.right() - 10.0);
        assert_eq!(top_right.top(), plot.top() + 10.0);
        // A curve along the top: the legend moves to the bottom right.
        let along_top: Vec<(f32, f32)> = (60..776).map(|x| (x as f32, 70.0)).collect();
        let moved = legend_box(&plot, &names, &along_top).unwrap();
        assert_eq!(moved.right(), plot.right() - 10.0);
        assert_eq!(moved.bottom(), plot.bottom() - 10.0);
    }

    #[test]
    fn long_names_are_shortened() {
        let long = "x".repeat(100);
        assert_eq!(legend_name(&long).chars().count(), MAX_NAME_CHARS);
        assert_eq!(legend_name("loss"), "loss");
    }
}
