//! Does sharpening a monocular map's depth edges improve the views
//! synthesised from one image (issue 60)? Monocular depth blurs across
//! object edges, and a warp by a blurred map smears the foreground's border
//! into the background ("flying pixels"). *Learning Stereo from Single
//! Images* (MfS; `datasets/warp_dataset.py`, `process_disparity`) removes the
//! pixels whose disparity's Sobel magnitude (scikit-image's `sobel`:
//! `sqrt((gx² + gy²) / 2)`, kernels `[1, 2, 1] / 4 ⊗ [1, 0, -1]`, borders
//! reflected) exceeds 3 and refills them with the nearest remaining pixel
//! (`griddata(..., method='nearest')`). (MfS also drops pixels of disparity
//! 0 from the sources, a side effect of marking edges with 0; here only the
//! edge pixels are removed.)
//!
//! What is measured, on the real multi-view scenes with ground truth:
//! Tsukuba (col3 and its truth → col1, col2, col4, col5), Teddy (im2 and
//! disp2 → im6, four steps right), and Baby2, Bowling2, Laundry (view1 and
//! disp1 → the six other views, view5 and disp5 → the six other views). For
//! each reference view, four one-step disparities:
//! - **FastDepth, fitted**: FastDepth's depth of the reference view, inverted, then
//!   fitted affinely (least squares over the pixels with ground truth) to
//!   the true one-step disparity, so that its scale and shift are right and
//!   mainly its shape (blurred edges) differs from the truth;
//! - **FastDepth, range**: FastDepth's depth scaled as the library scales a
//!   map by default (`virtual_disparity` with `Scaling::Range`: inverse
//!   depth, its largest value a fraction of the width), the fraction being
//!   the truth's (largest true disparity / width): the map as
//!   `views_from_one` gets it, with the true largest disparity;
//! - **truth at 224 px**: the true disparity (unknown pixels filled from the
//!   background side) area-averaged down to 224 x 224, FastDepth's input
//!   size, and bilinearly back up: the truth with the blur of FastDepth's
//!   resolution only;
//! - **truth**: the ground truth itself, as the ceiling (no treatment).
//!
//! Each real camera `s` steps away is synthesised as
//! `Extrapolator::views_from_one` makes it (`synthesize` of `|s|` times the
//! map, no dilation, background fill), with the map treated by:
//! - `none`;
//! - `MfS t`: pixels whose Sobel magnitude exceeds `t` (2, 3, 4) removed and
//!   refilled from the nearest remaining pixel (Euclidean);
//! - `background t`: the same pixels set invalid and filled by
//!   `mbs_warp::fill_disparity_background` (each row run takes the smaller,
//!   farther, of its two sides' disparities);
//!
//! each applied either to the map of each warp (`|s|` times the one-step
//! map: the threshold is on the warp's own disparity, as MfS applies it to
//! the disparity it warps by) or once to the one-step map (`@1`).
//!
//! Each view is scored by PSNR against the real view over all pixels, and
//! over the pixels no treatment of that disparity synthesised (the
//! complement of the union of their masks, so that every treatment is
//! scored on the same pixels). A scene's score is the mean over its views;
//! the table's mean is over the scenes, and "worst" is the largest loss of
//! one scene against `none`. Decision rule (issue 60): keep a treatment if
//! on FastDepth's maps (both scalings) its mean all-pixel PSNR gain is at
//! least 0.1 dB and no scene loses more than 0.1 dB (marked `keep`).
//!
//! Needs ONNX Runtime and the FastDepth model, and the ground truth of the
//! 7-view scenes, which is not shipped (`../shared/data` in the team's
//! checkout):
//!
//! ```text
//! export ORT_DYLIB_PATH=$(bash tools/setup-ort.sh | tail -1)
//! bash tools/setup-depth-model.sh
//! cargo run -p mbs-extrapolate --example mono_edges -- \
//!     [--model .models/fastdepth_7.onnx] [--card fastdepth] [--shared ../shared/data]
//! ```
//!
//! Another depth model is measured with `--model FILE --card CARD` (any
//! kind: metric depth is inverted before the fit, an inverse map is fitted
//! as it is); the blurred truth stays at FastDepth's 224 px.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use mbs_core::formats::read_disparity;
use mbs_core::formats::rgb::read_rgb;
use mbs_core::{FloatImage, MaskImage, RgbImage, Side};
use mbs_extrapolate::Extrapolator;
use mbs_extrapolate::evaluation::mask_union;
use mbs_extrapolate::mono::{Scaling, virtual_disparity};
use mbs_image::quality::psnr;
use mbs_infer::DepthKind;
use mbs_infer::inpaint::BackgroundFill;
use mbs_infer::onnx::resize::resize_bilinear;
use mbs_infer::onnx::{ModelCard, OnnxDepth, RuntimeOptions};
use mbs_warp::{Dilation, fill_disparity_background};
use rayon::prelude::*;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error + Send + Sync>>;

/// FastDepth's input size (its card's fixed size).
const FASTDEPTH_SIZE: u32 = 224;

/// One reference view of a scene, its true one-step disparity and the real
/// views it is scored against.
struct Reference {
    scene: &'static str,
    name: String,
    image: RgbImage,
    /// One view step's disparity, `+inf` where unknown.
    truth: FloatImage,
    /// `(steps, view)`: the real view `steps` cameras to the right (left
    /// when negative).
    targets: Vec<(i32, RgbImage)>,
}

fn references(testdata: &Path, shared: &Path) -> Result<Vec<Reference>> {
    let mut refs = Vec::new();
    let tsukuba = testdata.join("middlebury-tsukuba-row3");
    let col = |k: i32| read_rgb(&tsukuba.join(format!("scene1.row3.col{k}.ppm")));
    refs.push(Reference {
        scene: "Tsukuba",
        name: "col3".into(),
        image: col(3)?,
        truth: read_disparity(&tsukuba.join("truedisp.row3.col3.pgm"), Some(16.0))?,
        targets: [1, 2, 4, 5]
            .into_iter()
            .map(|k| Ok((k - 3, col(k)?)))
            .collect::<Result<_>>()?,
    });
    let teddy = testdata.join("middlebury-teddy");
    // disp2 / 4 is the disparity between im2 and im6, four steps apart.
    refs.push(Reference {
        scene: "Teddy",
        name: "im2".into(),
        image: read_rgb(&teddy.join("im2.png"))?,
        truth: read_disparity(&teddy.join("disp2.png"), Some(16.0))?,
        targets: vec![(4, read_rgb(&teddy.join("im6.png"))?)],
    });
    for (scene, folder) in [
        ("Baby2", "middlebury-baby2"),
        ("Bowling2", "middlebury-bowling2"),
        ("Laundry", "middlebury-laundry"),
    ] {
        let views: Vec<RgbImage> = (0..7)
            .map(|k| read_rgb(&testdata.join(folder).join(format!("view{k}.png"))))
            .collect::<std::result::Result<_, _>>()?;
        for r in [1, 5] {
            // value / 3 between view1 and view5 (4 steps): value / 12 a step.
            let truth = read_disparity(
                &shared.join(folder).join(format!("disp{r}.png")),
                Some(12.0),
            )?;
            refs.push(Reference {
                scene,
                name: format!("view{r}"),
                image: views[r as usize].clone(),
                truth,
                targets: (0..7)
                    .filter(|&k| k != r)
                    .map(|k| (k - r, views[k as usize].clone()))
                    .collect(),
            });
        }
    }
    Ok(refs)
}

/// `map` times `factor`.
fn times(map: &FloatImage, factor: f32) -> FloatImage {
    let mut out = map.clone();
    out.iter_mut().for_each(|v| *v *= factor);
    out
}

/// The inverse of `depth` (of kind `kind`: metric depth is inverted, an
/// inverse map taken as it is).
fn inverse(depth: f32, kind: DepthKind) -> f64 {
    match kind {
        DepthKind::MetricDepth => 1.0 / f64::from(depth),
        DepthKind::InverseRelative | DepthKind::Disparity => f64::from(depth),
    }
}

/// The model's inverse depth fitted affinely (least squares) to the finite
/// pixels of `truth`, clamped at 0; and the fit's RMS error (px).
fn fitted(depth: &FloatImage, kind: DepthKind, truth: &FloatImage) -> (FloatImage, f64) {
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (z, t) in depth.iter().zip(truth.iter()) {
        if t.is_finite() {
            let x = inverse(*z, kind);
            let y = f64::from(*t);
            n += 1.0;
            sx += x;
            sy += y;
            sxx += x * x;
            sxy += x * y;
        }
    }
    let a = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    let b = (sy - a * sx) / n;
    let mut map = depth.clone();
    map.iter_mut()
        .for_each(|z| *z = (a * inverse(*z, kind) + b).max(0.0) as f32);
    let (mut se, mut count) = (0.0, 0.0);
    for (d, t) in map.iter().zip(truth.iter()) {
        if t.is_finite() {
            se += (f64::from(*d) - f64::from(*t)).powi(2);
            count += 1.0;
        }
    }
    (map, (se / count).sqrt())
}

/// `map` area-averaged to `width` x `height` (each output pixel the mean of
/// the source area it covers).
fn area_down(map: &FloatImage, width: u32, height: u32) -> FloatImage {
    // Per output index: (source index, weight) pairs along one axis.
    let taps = |n: u32, src: u32| -> Vec<Vec<(usize, f64)>> {
        let ratio = f64::from(src) / f64::from(n);
        (0..n)
            .map(|i| {
                let (lo, hi) = (f64::from(i) * ratio, f64::from(i + 1) * ratio);
                (lo.floor() as usize..(hi.ceil() as usize).min(src as usize))
                    .map(|s| {
                        let overlap = (hi.min(s as f64 + 1.0) - lo.max(s as f64)).max(0.0);
                        (s, overlap / ratio)
                    })
                    .collect()
            })
            .collect()
    };
    let (xs, ys) = (taps(width, map.width()), taps(height, map.height()));
    FloatImage::from_fn(width, height, |x, y| {
        let mut sum = 0.0;
        for &(sy, wy) in &ys[y as usize] {
            for &(sx, wx) in &xs[x as usize] {
                sum += wy * wx * f64::from(map.get_pixel(sx as u32, sy as u32).0[0]);
            }
        }
        image::Luma([sum as f32])
    })
}

/// The truth (filled) blurred by FastDepth's resolution: down to 224 x 224
/// by area, back up bilinearly.
fn blurred_224(truth: &FloatImage) -> FloatImage {
    let filled = fill_disparity_background(truth);
    let small = area_down(&filled, FASTDEPTH_SIZE, FASTDEPTH_SIZE);
    resize_bilinear(&small, truth.width(), truth.height())
}

/// scikit-image's `sobel` magnitude of `map`: `sqrt((gx² + gy²) / 2)` with
/// the kernels `[1, 2, 1] / 4 ⊗ [1, 0, -1]`, borders reflected (the edge
/// pixel repeated).
fn sobel_magnitude(map: &FloatImage) -> Vec<f32> {
    let (w, h) = (map.width() as i64, map.height() as i64);
    let v = |x: i64, y: i64| map.as_raw()[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize];
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let gx = (v(x + 1, y - 1) - v(x - 1, y - 1))
                + 2.0 * (v(x + 1, y) - v(x - 1, y))
                + (v(x + 1, y + 1) - v(x - 1, y + 1));
            let gy = (v(x - 1, y + 1) - v(x - 1, y - 1))
                + 2.0 * (v(x, y + 1) - v(x, y - 1))
                + (v(x + 1, y + 1) - v(x + 1, y - 1));
            let (gx, gy) = (gx / 4.0, gy / 4.0);
            out.push(((gx * gx + gy * gy) / 2.0).sqrt());
        }
    }
    out
}

/// Pixels whose Sobel magnitude is above `threshold` (or not a number).
fn edges(map: &FloatImage, threshold: f32) -> Vec<bool> {
    sobel_magnitude(map)
        .into_iter()
        .map(|m| m.is_nan() || m > threshold)
        .collect()
}

/// `map` with its `removed` pixels replaced by the value of the nearest
/// kept pixel (Euclidean; an exact distance transform, Felzenszwalb and
/// Huttenlocher 2012, that keeps the nearest pixel's position).
fn fill_nearest(map: &FloatImage, removed: &[bool]) -> FloatImage {
    let (w, h) = (map.width() as usize, map.height() as usize);
    if removed.iter().all(|&r| r) {
        return map.clone();
    }
    // Per column: the row of the nearest kept pixel (the upper one on a tie).
    let mut nearest_row = vec![usize::MAX; w * h];
    for x in 0..w {
        let mut last = None;
        for y in 0..h {
            if !removed[y * w + x] {
                last = Some(y);
            }
            if let Some(l) = last {
                nearest_row[y * w + x] = l;
            }
        }
        let mut next = None;
        for y in (0..h).rev() {
            if !removed[y * w + x] {
                next = Some(y);
            }
            if let Some(n) = next {
                let i = y * w + x;
                if nearest_row[i] == usize::MAX || n - y < y - nearest_row[i] {
                    nearest_row[i] = n;
                }
            }
        }
    }
    let mut out = map.as_raw().clone();
    let mut f = vec![f64::INFINITY; w];
    let mut column = vec![0usize; w];
    for y in 0..h {
        for x in 0..w {
            let r = nearest_row[y * w + x];
            f[x] = if r == usize::MAX {
                f64::INFINITY
            } else {
                (r.abs_diff(y) as f64).powi(2)
            };
        }
        lower_envelope(&f, &mut column);
        for x in 0..w {
            if removed[y * w + x] {
                let q = column[x];
                let r = nearest_row[y * w + q];
                out[y * w + x] = map.as_raw()[r * w + q];
            }
        }
    }
    FloatImage::from_raw(map.width(), map.height(), out).expect("one value per pixel")
}

/// For each `x`, the `q` minimising `(x - q)² + f[q]` (finite `f` only;
/// the smaller `q` on a tie).
fn lower_envelope(f: &[f64], argmin: &mut [usize]) {
    let mut sites: Vec<usize> = Vec::with_capacity(f.len());
    let mut starts: Vec<f64> = Vec::with_capacity(f.len());
    for (q, &fq) in f.iter().enumerate() {
        if !fq.is_finite() {
            continue;
        }
        loop {
            let Some(&p) = sites.last() else {
                sites.push(q);
                starts.push(f64::NEG_INFINITY);
                break;
            };
            let (qf, pf) = (q as f64, p as f64);
            let s = ((fq + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf));
            if s <= *starts.last().unwrap_or(&f64::NEG_INFINITY) {
                sites.pop();
                starts.pop();
            } else {
                sites.push(q);
                starts.push(s);
                break;
            }
        }
    }
    let mut k = 0;
    for (x, out) in argmin.iter_mut().enumerate() {
        while k + 1 < sites.len() && starts[k + 1] < x as f64 {
            k += 1;
        }
        *out = sites[k];
    }
}

/// `map` with the pixels above `threshold` set invalid and filled from the
/// background side.
fn fill_background_at_edges(map: &FloatImage, removed: &[bool]) -> FloatImage {
    let mut out = map.clone();
    for (v, &r) in out.iter_mut().zip(removed) {
        if r {
            *v = f32::INFINITY;
        }
    }
    fill_disparity_background(&out)
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Fill {
    None,
    Nearest(f32),
    Background(f32),
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Treatment {
    fill: Fill,
    /// Applied once to the one-step map (else to each warp's map).
    on_one_step: bool,
}

impl Treatment {
    fn name(&self) -> String {
        let at = if self.on_one_step { " @1" } else { "" };
        match self.fill {
            Fill::None => "none".into(),
            Fill::Nearest(t) => format!("MfS {t}{at}"),
            Fill::Background(t) => format!("background {t}{at}"),
        }
    }

    fn apply(&self, map: &FloatImage) -> (FloatImage, f64) {
        let share =
            |removed: &[bool]| removed.iter().filter(|&&r| r).count() as f64 / removed.len() as f64;
        match self.fill {
            Fill::None => (map.clone(), 0.0),
            Fill::Nearest(t) => {
                let removed = edges(map, t);
                (fill_nearest(map, &removed), share(&removed))
            }
            Fill::Background(t) => {
                let removed = edges(map, t);
                (fill_background_at_edges(map, &removed), share(&removed))
            }
        }
    }

    /// The map camera `steps` away is warped by.
    fn warp_map(&self, one_step: &FloatImage, steps: i32) -> (FloatImage, f64) {
        let k = steps.unsigned_abs() as f32;
        if self.on_one_step {
            let (treated, share) = self.apply(one_step);
            (times(&treated, k), share)
        } else {
            self.apply(&times(one_step, k))
        }
    }
}

fn treatments() -> Vec<Treatment> {
    let mut all = vec![Treatment {
        fill: Fill::None,
        on_one_step: false,
    }];
    for on_one_step in [false, true] {
        for t in [2.0, 3.0, 4.0] {
            all.push(Treatment {
                fill: Fill::Nearest(t),
                on_one_step,
            });
        }
        for t in [2.0, 3.0, 4.0] {
            all.push(Treatment {
                fill: Fill::Background(t),
                on_one_step,
            });
        }
    }
    all
}

/// Scores of one treatment on one scene, summed over its views.
#[derive(Debug, Default, Clone, Copy)]
struct Sum {
    all: f64,
    kept: f64,
    edge_share: f64,
    views: usize,
}

/// Synthesises every target of `reference` from `one_step` under each
/// treatment and scores them; `sums[treatment]` gains each view's scores.
fn measure(
    reference: &Reference,
    one_step: &FloatImage,
    treatments: &[Treatment],
    extrapolator: &Extrapolator,
) -> Result<Vec<Sum>> {
    let per_target: Vec<Vec<(RgbImage, MaskImage, f64)>> = reference
        .targets
        .par_iter()
        .map(|(steps, _)| {
            let side = if *steps < 0 { Side::Left } else { Side::Right };
            treatments
                .iter()
                .map(|t| {
                    let (map, share) = t.warp_map(one_step, *steps);
                    let view = extrapolator.synthesize(&reference.image, &map, side, "view")?;
                    Ok((view.image, view.mask, share))
                })
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<_>>()?;
    let mut sums = vec![Sum::default(); treatments.len()];
    for ((_, real), views) in reference.targets.iter().zip(&per_target) {
        let union = views
            .iter()
            .skip(1)
            .fold(views[0].1.clone(), |u, v| mask_union(&u, &v.1));
        let mut kept = union;
        kept.iter_mut()
            .for_each(|m| *m = if *m > 0 { 0 } else { 255 });
        for (sum, (image, _, share)) in sums.iter_mut().zip(views) {
            sum.all += psnr(image, real, None).ok_or("size")?;
            sum.kept += psnr(image, real, Some(&kept)).ok_or("no pixel kept")?;
            sum.edge_share += share;
            sum.views += 1;
        }
    }
    Ok(sums)
}

fn arg(args: &[String], name: &str) -> Option<PathBuf> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from)
}

/// The maps measured, in the tables' order (`{}` is the model's card); the
/// last (the truth) only untreated.
const PROXIES: [&str; 4] = ["{}, fitted", "{}, range", "truth at 224 px", "truth"];

/// The one-step maps of `r`, one per proxy.
fn proxy_maps(r: &Reference, depth: &OnnxDepth) -> Result<[FloatImage; 4]> {
    let map = depth.predict(&r.image)?;
    let (fitted, rmse) = fitted(&map.values, map.kind, &r.truth);
    let largest = r
        .truth
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .fold(0.0f32, f32::max);
    let fraction = largest / r.truth.width() as f32;
    let range = Scaling::Range {
        low: fraction,
        high: fraction,
        seed: 0,
    };
    let ranged = virtual_disparity(&map.values, map.kind, range, &r.name)?.map;
    eprintln!(
        "{} {}: FastDepth fitted with an RMS error of {rmse:.2} px a step; \
         largest true disparity {largest:.2} px a step",
        r.scene, r.name
    );
    Ok([
        fitted,
        ranged,
        blurred_224(&r.truth),
        fill_disparity_background(&r.truth),
    ])
}

/// Per proxy and scene, the sums of each treatment.
type Table = BTreeMap<(usize, &'static str), Vec<Sum>>;

fn measure_all(refs: &[Reference], depth: &OnnxDepth, treatments: &[Treatment]) -> Result<Table> {
    let extrapolator = Extrapolator::new(Dilation::None, Box::new(BackgroundFill::default()));
    let mut table = Table::new();
    for r in refs {
        for (p, one_step) in proxy_maps(r, depth)?.iter().enumerate() {
            let which = if p + 1 == PROXIES.len() {
                &treatments[..1]
            } else {
                treatments
            };
            let sums = measure(r, one_step, which, &extrapolator)?;
            let entry = table
                .entry((p, r.scene))
                .or_insert_with(|| vec![Sum::default(); sums.len()]);
            for (e, s) in entry.iter_mut().zip(sums) {
                e.all += s.all;
                e.kept += s.kept;
                e.edge_share += s.edge_share;
                e.views += s.views;
            }
        }
    }
    Ok(table)
}

/// One row of a proxy's table: per scene, then the mean, the gain and the
/// worst scene against `none` (row 0), and whether the rule keeps it.
fn print_row(sums: &[&[Sum]], row: usize, name: &str, judged: bool) {
    let mean = |s: &Sum| {
        let n = s.views as f64;
        (s.all / n, s.kept / n, s.edge_share / n)
    };
    let n = sums.len() as f64;
    let (mut all, mut kept, mut share, mut gain_all, mut gain_kept) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut worst_all, mut worst_kept) = (f64::INFINITY, f64::INFINITY);
    print!("| {name} |");
    for scene in sums {
        let ((a, k, e), (a0, k0, _)) = (mean(&scene[row]), mean(&scene[0]));
        print!(" {a:.2} / {k:.2} |");
        (all, kept, share) = (all + a / n, kept + k / n, share + e / n);
        (gain_all, gain_kept) = (gain_all + (a - a0) / n, gain_kept + (k - k0) / n);
        (worst_all, worst_kept) = (worst_all.min(a - a0), worst_kept.min(k - k0));
    }
    let keep = judged && row > 0 && gain_all >= 0.1 && worst_all >= -0.1;
    println!(
        " {all:.2} / {kept:.2} | {gain_all:+.2} ({gain_kept:+.2}) | {worst_all:+.2} ({worst_kept:+.2}) | {:.1} % |{}",
        100.0 * share,
        if keep { " keep" } else { "" }
    );
}

fn print_tables(table: &Table, scenes: &[&'static str], treatments: &[Treatment], model: &str) {
    for (p, proxy) in PROXIES.iter().enumerate() {
        let proxy = proxy.replace("{}", model);
        let sums: Vec<&[Sum]> = scenes.iter().map(|s| &table[&(p, *s)][..]).collect();
        println!("\n### {proxy}\n");
        print!("| treatment |");
        for s in scenes {
            print!(" {s} |");
        }
        println!(" mean | gain | worst scene | edge pixels |");
        println!("|---|{}---:|---:|---:|---:|", "---:|".repeat(scenes.len()));
        for (row, treatment) in treatments.iter().enumerate().take(sums[0].len()) {
            print_row(&sums, row, &treatment.name(), p < 2);
        }
    }
    println!(
        "\nCells: PSNR (dB) over all pixels / over the pixels no treatment synthesised. \
         Gain: mean over the scenes against `none`, all pixels (non-synthesised pixels). \
         Worst scene: the largest loss of one scene, likewise. Edge pixels: the share \
         of pixels the treatment refilled. `keep`: passes the rule on the model's maps."
    );
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let model = arg(&args, "--model").unwrap_or_else(|| root.join(".models/fastdepth_7.onnx"));
    let shared = arg(&args, "--shared").unwrap_or_else(|| root.join("../shared/data"));
    let refs = references(&root.join("testdata"), &shared)?;
    let card = args
        .iter()
        .position(|a| a == "--card")
        .and_then(|i| args.get(i + 1))
        .map_or("fastdepth", String::as_str);
    let depth = OnnxDepth::open(&model, ModelCard::load(card)?, &RuntimeOptions::default())?;
    let treatments = treatments();
    let table = measure_all(&refs, &depth, &treatments)?;
    let mut scenes: Vec<&'static str> = refs.iter().map(|r| r.scene).collect();
    scenes.dedup();
    print_tables(&table, &scenes, &treatments, &depth.card().name);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(width: u32, values: &[f32]) -> FloatImage {
        FloatImage::from_vec(width, values.len() as u32 / width, values.to_vec()).unwrap()
    }

    #[test]
    fn a_step_of_8_has_a_sobel_magnitude_of_8_over_root_2_beside_it() {
        let step = map(4, &[0.0, 0.0, 8.0, 8.0].repeat(3));
        let row = [0.0, 8.0 / 2f32.sqrt(), 8.0 / 2f32.sqrt(), 0.0];
        assert_eq!(sobel_magnitude(&step), row.repeat(3));
        assert_eq!(edges(&step, 3.0), [false, true, true, false].repeat(3));
        assert_eq!(edges(&step, 6.0), [false; 12]);
    }

    #[test]
    fn removed_pixels_take_the_nearest_kept_pixel() {
        // A row: the tie in the middle goes to the left.
        let row = map(5, &[1.0, 0.0, 0.0, 0.0, 9.0]);
        let removed = [false, true, true, true, false];
        assert_eq!(
            fill_nearest(&row, &removed).as_raw(),
            &[1.0, 1.0, 1.0, 9.0, 9.0]
        );
        // 3 x 3 with (0, 0) = 1 and (2, 1) = 5 kept: Euclidean nearest.
        let mut grid = map(3, &[0.0; 9]);
        grid.put_pixel(0, 0, image::Luma([1.0]));
        grid.put_pixel(2, 1, image::Luma([5.0]));
        let removed: Vec<bool> = (0..9).map(|i| i != 0 && i != 5).collect();
        #[rustfmt::skip]
        let expected = [
            1.0, 1.0, 5.0,
            1.0, 5.0, 5.0,
            1.0, 5.0, 5.0,
        ];
        assert_eq!(fill_nearest(&grid, &removed).as_raw(), &expected);
    }

    #[test]
    fn the_nearest_fill_is_at_the_least_euclidean_distance() {
        // Each pixel's value is its index, so the fill says where it came
        // from; 70 % of the pixels removed, pseudo-randomly.
        let (w, h) = (23usize, 17usize);
        let grid = map(w as u32, &(0..w * h).map(|i| i as f32).collect::<Vec<_>>());
        let removed: Vec<bool> = (0..w * h)
            .map(|i| (i as u64).wrapping_mul(2_654_435_761) % 10 < 7)
            .collect();
        let filled = fill_nearest(&grid, &removed);
        let d2 =
            |i: usize, j: usize| (i % w).abs_diff(j % w).pow(2) + (i / w).abs_diff(j / w).pow(2);
        for i in 0..w * h {
            let from = filled.as_raw()[i] as usize;
            assert!(!removed[from], "pixel {i} took removed pixel {from}");
            let least = (0..w * h).filter(|&j| !removed[j]).map(|j| d2(i, j)).min();
            assert_eq!(Some(d2(i, from)), least, "pixel {i}");
        }
    }

    #[test]
    fn the_background_variant_fills_from_the_farther_side() {
        let row = map(4, &[2.0, 4.0, 7.0, 9.0]);
        let removed = [false, true, true, false];
        assert_eq!(
            fill_background_at_edges(&row, &removed).as_raw(),
            &[2.0, 2.0, 2.0, 9.0]
        );
    }

    #[test]
    fn the_area_average_keeps_the_mean() {
        let ramp = map(6, &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(area_down(&ramp, 3, 1).as_raw(), &[0.5, 2.5, 4.5]);
        // 1.5 source pixels an output pixel: (0 + 0.5) / 1.5, (0.5 + 2) / 1.5...
        let thirds = area_down(&ramp, 4, 1);
        for (got, want) in thirds.iter().zip([1.0, 5.0, 10.0, 14.0]) {
            assert!((got - want / 3.0).abs() < 1e-6, "{got} {want}");
        }
    }
}
