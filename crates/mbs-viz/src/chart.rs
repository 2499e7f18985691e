//! Line charts of training curves as PNG files, drawn with plotters: a
//! title, labelled axes with their units, a grid, a legend, and a linear or
//! logarithmic value axis. Text uses the embedded DejaVu Sans font, so the
//! charts look the same on every machine and need no system fonts.

use std::ops::Range;
use std::path::Path;
use std::sync::Once;

use mbs_core::RgbImage;
use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::VizError;

/// Canvas width in pixels.
pub const WIDTH: u32 = 900;
/// Canvas height in pixels.
pub const HEIGHT: u32 = 520;
/// The font family every text of a chart (and caption) is drawn in.
pub(crate) const FONT: &str = "sans-serif";
/// DejaVu Sans (licence in `fonts/LICENSE-DejaVu.txt`).
const FONT_TTF: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");
/// Series colours, in order (Matplotlib's "tab10"); more series reuse them.
pub const PALETTE: [[u8; 3]; 10] = [
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

/// One curve of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Shown in the legend.
    pub name: String,
    /// (x, y) points in drawing order.
    pub points: Vec<(f64, f64)>,
}

/// A chart of one or more curves over a shared x axis.
#[derive(Debug, Clone, PartialEq)]
pub struct LineChart {
    /// Drawn above the plot.
    pub title: String,
    /// The x axis's name with its unit, e.g. "training step".
    pub x_label: String,
    /// The y axis's name with its unit, e.g. "Out-3 (%)".
    pub y_label: String,
    /// A logarithmic value axis (for losses spanning decades).
    pub log_y: bool,
    /// The curves, coloured by [`PALETTE`] in order.
    pub series: Vec<Series>,
}

/// Registers the embedded font with plotters, once per process.
pub(crate) fn register_embedded_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TTF compiled into the binary; a failure
        // would show as missing text, which the tests would catch.
        let _ = register_font(FONT, FontStyle::Normal, FONT_TTF);
    });
}

/// The colour of the `index`-th series.
pub fn series_color(index: usize) -> [u8; 3] {
    PALETTE[index % PALETTE.len()]
}

/// `[min, max]` widened by `pad` of its span (or around a lone value).
fn padded(min: f64, max: f64, pad: f64, log: bool) -> Range<f64> {
    if log {
        let (lo, hi) = (min.log10(), max.log10());
        let span = (hi - lo).max(0.2);
        let mid = (hi + lo) / 2.0;
        let (lo, hi) = (
            lo.min(mid - span / 2.0) - pad * span,
            hi.max(mid + span / 2.0) + pad * span,
        );
        return 10f64.powf(lo)..10f64.powf(hi);
    }
    let span = max - min;
    let span = if span > 0.0 { span } else { min.abs().max(1.0) };
    let mid = (min + max) / 2.0;
    (min.min(mid - span / 2.0) - pad * span)..(max.max(mid + span / 2.0) + pad * span)
}

impl LineChart {
    /// The points of each series that can be drawn: finite, and positive on
    /// a log axis.
    fn drawable(&self) -> Vec<Vec<(f64, f64)>> {
        self.series
            .iter()
            .map(|s| {
                s.points
                    .iter()
                    .copied()
                    .filter(|&(x, y)| x.is_finite() && y.is_finite() && (!self.log_y || y > 0.0))
                    .collect()
            })
            .collect()
    }

    /// Draws the chart into a [`WIDTH`] x [`HEIGHT`] RGB image. Points with
    /// a non-finite coordinate are left out (the line joins their
    /// neighbours), and so are values <= 0 on a log axis. It is an error if
    /// there is no series or no series has a point left to draw.
    pub fn render(&self) -> Result<RgbImage, VizError> {
        if self.series.is_empty() {
            return Err(VizError::Input("no series to plot".into()));
        }
        let curves = self.drawable();
        let mut all = curves.iter().flatten();
        let Some(&(x0, y0)) = all.next() else {
            let what = if self.log_y {
                "finite positive"
            } else {
                "finite"
            };
            return Err(VizError::Input(format!(
                "no {what} point to plot in {} series",
                self.series.len()
            )));
        };
        let (mut x_min, mut x_max, mut y_min, mut y_max) = (x0, x0, y0, y0);
        for &(x, y) in all {
            (x_min, x_max) = (x_min.min(x), x_max.max(x));
            (y_min, y_max) = (y_min.min(y), y_max.max(y));
        }
        register_embedded_font();
        let mut buffer = vec![255u8; WIDTH as usize * HEIGHT as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut buffer, (WIDTH, HEIGHT)).into_drawing_area();
            let x_range = padded(x_min, x_max, 0.02, false);
            let y_range = padded(y_min, y_max, 0.05, self.log_y);
            let (corner, y_range) = self.legend_place(&curves, &x_range, y_range);
            let drawn = if self.log_y {
                self.draw(&root, &curves, x_range, y_range.log_scale(), corner)
            } else {
                self.draw(&root, &curves, x_range, y_range, corner)
            };
            drawn.map_err(VizError::Draw)?;
            root.present().map_err(|e| VizError::Draw(e.to_string()))?;
        }
        RgbImage::from_raw(WIDTH, HEIGHT, buffer)
            .ok_or_else(|| VizError::Draw("the chart buffer has the wrong size".into()))
    }

    /// Draws axes, grid, curves and legend with the value axis `y`.
    fn draw<Y>(
        &self,
        root: &DrawingArea<BitMapBackend<'_>, Shift>,
        curves: &[Vec<(f64, f64)>],
        x: Range<f64>,
        y: Y,
        legend: SeriesLabelPosition,
    ) -> Result<(), String>
    where
        Y: AsRangedCoord<Value = f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let err = |e: DrawingAreaErrorKind<_>| e.to_string();
        root.fill(&WHITE).map_err(err)?;
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, (FONT, 24))
            .margin(14)
            .x_label_area_size(52)
            .y_label_area_size(78)
            .build_cartesian_2d(x, y)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .axis_desc_style((FONT, 17))
            .label_style((FONT, 14))
            .x_max_light_lines(1)
            .y_max_light_lines(1)
            .light_line_style(RGBColor(238, 238, 238))
            .bold_line_style(RGBColor(215, 215, 215))
            .x_label_formatter(&|v| format_tick(*v))
            .y_label_formatter(&|v| format_tick(*v))
            .draw()
            .map_err(err)?;
        self.draw_curves(&mut chart, curves)?;
        chart
            .configure_series_labels()
            .position(legend)
            .label_font((FONT, 15))
            .background_style(WHITE.mix(0.9))
            .border_style(RGBColor(170, 170, 170))
            .draw()
            .map_err(err)
    }

    /// Draws each series in its colour, as a line or, for a lone point, a
    /// dot, and gives it its legend entry.
    fn draw_curves<'a, Y>(
        &self,
        chart: &mut ChartContext<'a, BitMapBackend<'a>, Cartesian2d<RangedCoordf64, Y>>,
        curves: &[Vec<(f64, f64)>],
    ) -> Result<(), String>
    where
        Y: Ranged<ValueType = f64>,
    {
        let err = |e: DrawingAreaErrorKind<_>| e.to_string();
        for (index, (series, points)) in self.series.iter().zip(curves).enumerate() {
            let [r, g, b] = series_color(index);
            let style = RGBColor(r, g, b).stroke_width(2);
            let drawn = if points.len() == 1 {
                chart
                    .draw_series(PointSeries::of_element(
                        points.iter().copied(),
                        4,
                        style.filled(),
                        &|c, s, st| Circle::new(c, s, st),
                    ))
                    .map_err(err)?
            } else {
                chart
                    .draw_series(LineSeries::new(points.iter().copied(), style))
                    .map_err(err)?
            };
            drawn.label(series.name.clone()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 22, y)], RGBColor(r, g, b).stroke_width(3))
            });
        }
        Ok(())
    }

    /// Share of the plot's height the legend box takes.
    fn legend_height(&self) -> f64 {
        (0.065 * (self.series.len() as f64 + 1.0)).min(0.6)
    }

    /// Where the legend goes: the emptiest corner, or, when the curves pass
    /// every corner, the upper right above headroom added to the value axis.
    fn legend_place(
        &self,
        curves: &[Vec<(f64, f64)>],
        x: &Range<f64>,
        y: Range<f64>,
    ) -> (SeriesLabelPosition, Range<f64>) {
        let (corner, hidden) = self.emptiest_corner(curves, x, &y);
        if hidden == 0 {
            return (corner, y);
        }
        let grow = 1.0 / (1.0 - self.legend_height());
        let top = if self.log_y {
            y.start * (y.end / y.start).powf(grow)
        } else {
            y.start + (y.end - y.start) * grow
        };
        (SeriesLabelPosition::UpperRight, y.start..top)
    }

    /// The corner of the plot where the legend hides the fewest points,
    /// upper right first, with the number of points it hides.
    fn emptiest_corner(
        &self,
        curves: &[Vec<(f64, f64)>],
        x: &Range<f64>,
        y: &Range<f64>,
    ) -> (SeriesLabelPosition, usize) {
        let scale = |v: f64| if self.log_y { v.log10() } else { v };
        let (y0, y1) = (scale(y.start), scale(y.end));
        let fraction = |(px, py): (f64, f64)| {
            (
                (px - x.start) / (x.end - x.start),
                (scale(py) - y0) / (y1 - y0),
            )
        };
        // The legend box covers about this share of the plot from a corner.
        let (width, height) = (0.3, self.legend_height());
        let hidden = |right: bool, top: bool| {
            curves
                .iter()
                .flatten()
                .map(|&p| fraction(p))
                .filter(|&(fx, fy)| {
                    let in_x = if right { fx > 1.0 - width } else { fx < width };
                    let in_y = if top { fy > 1.0 - height } else { fy < height };
                    in_x && in_y
                })
                .count()
        };
        [
            (SeriesLabelPosition::UpperRight, true, true),
            (SeriesLabelPosition::UpperLeft, false, true),
            (SeriesLabelPosition::LowerRight, true, false),
            (SeriesLabelPosition::LowerLeft, false, false),
        ]
        .into_iter()
        .map(|(corner, right, top)| (corner, hidden(right, top)))
        .min_by_key(|&(_, n)| n)
        .unwrap_or((SeriesLabelPosition::UpperRight, 0))
    }

    /// Draws the chart into a PNG at `path`, written atomically.
    pub fn write_png(&self, path: &Path) -> Result<(), VizError> {
        let image = self.render().map_err(|e| match e {
            VizError::Input(m) => VizError::Input(format!("{}: {m}", path.display())),
            other => other,
        })?;
        mbs_core::formats::rgb::write_rgb_png(path, &image)?;
        Ok(())
    }
}

/// A tick label: at most three significant digits without trailing
/// zeros, scientific for tiny or huge magnitudes.
pub(crate) fn format_tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        return "0".into();
    }
    if !(1e-3..1e6).contains(&a) {
        return format!("{v:.0e}");
    }
    let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
    let text = format!("{v:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart(series: Vec<Series>, log_y: bool) -> LineChart {
        LineChart {
            title: "S3 loss terms".into(),
            x_label: "training step".into(),
            y_label: "loss (unweighted)".into(),
            log_y,
            series,
        }
    }

    fn series(name: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.into(),
            points,
        }
    }

    /// Pixels of exactly `rgb`.
    fn count(img: &RgbImage, rgb: [u8; 3]) -> usize {
        img.pixels().filter(|p| p.0 == rgb).count()
    }

    /// Dark (text or frame) pixels in the rectangle.
    fn dark(img: &RgbImage, x: Range<u32>, y: Range<u32>) -> usize {
        y.flat_map(|y| x.clone().map(move |x| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0.iter().all(|&c| c < 110))
            .count()
    }

    #[test]
    fn draws_each_series_in_its_colour_with_title_axes_and_legend() {
        let down = (0..200).map(|i| (i as f64 * 10.0, 2.0 / (1.0 + i as f64 * 0.1)));
        let flat = (0..200).map(|i| (i as f64 * 10.0, 0.05 + (i % 7) as f64 * 0.01));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("loss.png");
        chart(
            vec![
                series("geometry", down.collect()),
                series("smoothness", flat.collect()),
            ],
            true,
        )
        .write_png(&path)
        .unwrap();
        let img = image::open(&path).unwrap().into_rgb8();
        assert_eq!(img.dimensions(), (WIDTH, HEIGHT));
        assert_eq!(img.get_pixel(0, 0).0, [255, 255, 255]);
        for i in 0..2 {
            let n = count(&img, series_color(i));
            assert!(n > 300, "series {i}: {n} pixels of its colour");
        }
        // Title on top, the y label in the left margin, the x label and
        // tick labels at the bottom: text is dark pixels there.
        assert!(dark(&img, 250..650, 0..40) > 150, "title");
        assert!(dark(&img, 0..30, 100..420) > 100, "y axis label");
        assert!(
            dark(&img, 300..600, HEIGHT - 30..HEIGHT) > 100,
            "x axis label"
        );
        assert!(dark(&img, 30..90, 40..460) > 150, "y tick labels");
        // The legend: a swatch of each colour in the upper right corner.
        for i in 0..2 {
            let [r, g, b] = series_color(i);
            let swatch = (WIDTH - 320..WIDTH)
                .flat_map(|x| (30..130).map(move |y| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x, y).0 == [r, g, b])
                .count();
            assert!(swatch > 20, "legend swatch of series {i}: {swatch}");
        }
    }

    #[test]
    fn log_axes_draw_exponential_decay_straight() {
        // y = 10^(-x/100): on a log axis the curve is a straight line, so
        // its pixels' rows rise linearly with their columns.
        let decay: Vec<(f64, f64)> = (0..=300)
            .map(|i| (i as f64, 10f64.powf(-(i as f64) / 100.0)))
            .collect();
        let img = chart(vec![series("loss", decay)], true).render().unwrap();
        let colour = series_color(0);
        let pixels: Vec<(f64, f64)> = img
            .enumerate_pixels()
            .filter(|(x, _, p)| p.0 == colour && *x < WIDTH - 340)
            .map(|(x, y, _)| (f64::from(x), f64::from(y)))
            .collect();
        assert!(pixels.len() > 200, "{} pixels", pixels.len());
        // Least-squares line through the pixels; residuals stay small.
        let n = pixels.len() as f64;
        let (mx, my) = pixels
            .iter()
            .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x / n, b + y / n));
        let sxy: f64 = pixels.iter().map(|&(x, y)| (x - mx) * (y - my)).sum();
        let sxx: f64 = pixels.iter().map(|&(x, _)| (x - mx) * (x - mx)).sum();
        let slope = sxy / sxx;
        let worst = pixels
            .iter()
            .map(|&(x, y)| (y - (my + slope * (x - mx))).abs())
            .fold(0.0, f64::max);
        assert!(slope > 0.3, "slope {slope}");
        assert!(worst < 4.0, "worst residual {worst} px");
    }

    #[test]
    fn nothing_drawable_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("empty.png");
        for (log, points) in [(false, vec![(1.0, f64::NAN)]), (true, vec![(1.0, -2.0)])] {
            let err = chart(vec![series("x", points)], log)
                .write_png(&path)
                .unwrap_err();
            let msg = err.to_string();
            assert!(msg.contains("empty.png"), "{msg}");
            assert!(msg.contains("no finite"), "{msg}");
            assert!(!path.exists());
        }
        assert!(chart(Vec::new(), false).render().is_err());
    }

    #[test]
    fn a_single_point_and_a_constant_series_are_drawn() {
        let img = chart(
            vec![
                series("one", vec![(5.0, 3.0)]),
                series("flat", (0..50).map(|i| (i as f64, 3.0)).collect()),
            ],
            false,
        )
        .render()
        .unwrap();
        assert!(count(&img, series_color(0)) > 20);
        assert!(count(&img, series_color(1)) > 300);
    }

    #[test]
    fn the_legend_moves_off_the_curves() {
        // Points only in the upper right: any other corner is chosen.
        let corner_chart = chart(vec![series("a", vec![(90.0, 9.5), (95.0, 9.8)])], false);
        let (c, y) = corner_chart.legend_place(&corner_chart.drawable(), &(0.0..100.0), 0.0..10.0);
        assert!(!matches!(c, SeriesLabelPosition::UpperRight));
        assert_eq!(y, 0.0..10.0);
        // Nothing near the upper right: it stays there.
        let low = chart(vec![series("a", vec![(0.0, 0.0), (10.0, 1.0)])], false);
        let (c, _) = low.emptiest_corner(&low.drawable(), &(0.0..100.0), &(0.0..10.0));
        assert!(matches!(c, SeriesLabelPosition::UpperRight));
        // Curves through every corner: headroom above them for the legend.
        let zigzag: Vec<(f64, f64)> = (0..=100)
            .map(|i| (i as f64, (i % 2) as f64 * 10.0))
            .collect();
        let busy = chart(vec![series("z", zigzag)], false);
        let (c, y) = busy.legend_place(&busy.drawable(), &(0.0..100.0), 0.0..10.0);
        assert!(matches!(c, SeriesLabelPosition::UpperRight));
        assert!(y.end > 11.0 && y.start == 0.0, "{y:?}");
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(format_tick(0.0), "0");
        assert_eq!(format_tick(1500.0), "1500");
        assert_eq!(format_tick(2.5), "2.5");
        assert_eq!(format_tick(0.05), "0.05");
        assert_eq!(format_tick(0.1234), "0.123");
        assert_eq!(format_tick(0.9), "0.9");
        assert_eq!(format_tick(1e-5), "1e-5");
        assert_eq!(format_tick(2e7), "2e7");
    }
}
