//! One image into a multi-baseline set (as *Learning Stereo from Single
//! Images*, Watson et al. 2020, does for one pair): a monocular depth map
//! becomes the disparity of a virtual rig ([`virtual_disparity`]), and every
//! other camera of the rig is synthesised from the image alone by the same
//! warp, dilation and inpainting as `extrapolate`
//! ([`Extrapolator::views_from_one`]).
//!
//! The scaling to a virtual rig, and why ([`Scaling`]):
//! - **metric depth** with a focal length and baseline: `d = f·B/Z`, the
//!   disparity a real rig would see;
//! - **a range**, for any map (MfS's rule): the map as inverse depth (metric
//!   depth inverted, a relative model's output as it is), shifted so its
//!   least value is 0 if it is negative, then scaled so that its largest
//!   value is a fraction of the image's width drawn per image, uniformly in
//!   `[low, high]`, from the seed and the image's id only (not the order,
//!   shard or thread). A relative model's output has an unknown scale and
//!   shift; like MfS this keeps its zero as infinitely far and draws the
//!   scale, so the network sees many rigs;
//! - **as it is**, for a map that already is a disparity in pixels.

use mbs_core::{FloatImage, MaskImage, RgbImage, Side};
use mbs_infer::DepthKind;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::{ExtrapolateError, Extrapolator, NewView};

/// How a depth map becomes the disparity of one baseline of the virtual
/// rig (see the [module](self) docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scaling {
    /// The largest disparity is a fraction of the width drawn uniformly in
    /// `[low, high]` per image, from `seed` and the image's id.
    Range {
        /// Least fraction of the width.
        low: f32,
        /// Greatest fraction of the width.
        high: f32,
        /// The draw's seed.
        seed: u64,
    },
    /// `d = focal_px · baseline_m / Z` (metric depth only).
    Metric {
        /// The virtual rig's focal length, pixels.
        focal_px: f64,
        /// The virtual rig's baseline, metres.
        baseline_m: f64,
    },
    /// The map is a disparity in pixels already (disparity maps only).
    AsIs,
}

impl Scaling {
    /// The scaling's name in manifests: `range`, `metric` or `as-is`.
    pub fn key(&self) -> &'static str {
        match self {
            Scaling::Range { .. } => "range",
            Scaling::Metric { .. } => "metric",
            Scaling::AsIs => "as-is",
        }
    }
}

/// Which cameras a set from one image has: `views` cameras one baseline
/// apart, the image at camera `reference` (0-based).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ViewLayout {
    /// How many cameras (at least 2).
    pub views: usize,
    /// The image's camera.
    pub reference: usize,
}

impl ViewLayout {
    /// The paper's four cameras: one further left, the image, its right
    /// partner, one further right.
    pub const PAPER: ViewLayout = ViewLayout {
        views: 4,
        reference: 1,
    };

    /// The layout, or why not: fewer than two views, or a reference
    /// outside them.
    pub fn new(views: usize, reference: usize) -> Result<ViewLayout, String> {
        if views < 2 {
            return Err(format!("{views} views: a set needs at least 2"));
        }
        if reference >= views {
            return Err(format!(
                "reference camera {reference} is not one of the {views} views (0 to {})",
                views - 1
            ));
        }
        Ok(ViewLayout { views, reference })
    }
}

/// The disparity of one baseline drawn for an image, and what was drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct VirtualDisparity {
    /// The reference image's disparity against the camera one baseline
    /// away, pixels.
    pub map: FloatImage,
    /// With [`Scaling::Range`]: the drawn largest disparity as a fraction
    /// of the width.
    pub drawn_fraction: Option<f32>,
}

/// The fraction of the width drawn for the image `id` in `[low, high]`:
/// it depends on `seed` and `id` only.
pub fn draw_fraction(low: f32, high: f32, seed: u64, id: &str) -> f32 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(fnv1a64(id));
    low + rng.random::<f32>() * (high - low)
}

/// The 64-bit FNV-1a hash of `text`: a stable stream number per id.
fn fnv1a64(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |hash, byte| {
        (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The disparity of one baseline of the virtual rig for the depth `map`
/// of kind `kind` of the image `id`. A map its kind cannot hold (NaN, a
/// metric depth of zero, a constant map) or a scaling its kind does not
/// allow is an error.
pub fn virtual_disparity(
    map: &FloatImage,
    kind: DepthKind,
    scaling: Scaling,
    id: &str,
) -> Result<VirtualDisparity, ExtrapolateError> {
    if let Some(problem) = kind.problem(map) {
        return Err(ExtrapolateError::Depth(problem));
    }
    match (scaling, kind) {
        (Scaling::AsIs, DepthKind::Disparity) => Ok(VirtualDisparity {
            map: map.clone(),
            drawn_fraction: None,
        }),
        (
            Scaling::Metric {
                focal_px,
                baseline_m,
            },
            DepthKind::MetricDepth,
        ) => {
            let scale = focal_px * baseline_m;
            let mut disparity = map.clone();
            disparity
                .iter_mut()
                .for_each(|v| *v = (scale / f64::from(*v)) as f32);
            Ok(VirtualDisparity {
                map: disparity,
                drawn_fraction: None,
            })
        }
        (Scaling::Range { low, high, seed }, _) => {
            let mut inverse = map.clone();
            if kind == DepthKind::MetricDepth {
                inverse.iter_mut().for_each(|v| *v = 1.0 / *v);
            }
            let least = inverse.iter().copied().fold(f32::INFINITY, f32::min);
            if least < 0.0 {
                inverse.iter_mut().for_each(|v| *v -= least);
            }
            let largest = inverse.iter().copied().fold(0.0f32, f32::max);
            let fraction = draw_fraction(low, high, seed, id);
            let scale = fraction * map.width() as f32 / largest;
            inverse.iter_mut().for_each(|v| *v *= scale);
            Ok(VirtualDisparity {
                map: inverse,
                drawn_fraction: Some(fraction),
            })
        }
        (scaling, kind) => Err(ExtrapolateError::Depth(format!(
            "the {} scaling cannot take a map of kind {kind}: as-is takes a disparity, \
             metric takes metric depth, range takes any",
            scaling.key()
        ))),
    }
}

/// The cameras of a set from one image: the synthesised views, `None` at
/// the reference camera (the image itself).
#[derive(Debug, Clone, PartialEq)]
pub struct MonoViews {
    /// `views[k]` is camera `k`'s view and mask, synthesised.
    pub views: Vec<Option<NewView>>,
}

impl Extrapolator {
    /// Every camera of `layout` but the reference, synthesised from
    /// `reference` alone: camera `k` is `reference` warped by `|k - r|`
    /// times `disparity` (one baseline's) towards its side, then masked
    /// and inpainted by [`Extrapolator::synthesize`], exactly as
    /// `extrapolate` makes its new views. Views are named `image_{k+1}` in
    /// errors.
    pub fn views_from_one(
        &self,
        reference: &RgbImage,
        disparity: &FloatImage,
        layout: ViewLayout,
    ) -> Result<MonoViews, ExtrapolateError> {
        let r = layout.reference;
        let views = (0..layout.views)
            .map(|k| {
                let Some(side) = Side::of(r, k) else {
                    return Ok(None);
                };
                let steps = k.abs_diff(r) as f32;
                let scaled;
                let map = if steps == 1.0 {
                    disparity
                } else {
                    scaled = times(disparity, steps);
                    &scaled
                };
                let name = format!("image_{}", k + 1);
                self.synthesize(reference, map, side, &name).map(Some)
            })
            .collect::<Result<_, _>>()?;
        Ok(MonoViews { views })
    }
}

/// `map` times `factor`.
fn times(map: &FloatImage, factor: f32) -> FloatImage {
    let mut scaled = map.clone();
    scaled.iter_mut().for_each(|v| *v *= factor);
    scaled
}

impl MonoViews {
    /// The masks of synthesised pixels, `None` at the reference camera.
    pub fn masks(&self) -> Vec<Option<&MaskImage>> {
        self.views
            .iter()
            .map(|view| view.as_ref().map(|v| &v.mask))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_infer::inpaint::BackgroundFill;
    use mbs_warp::Dilation;

    fn map(values: &[f32]) -> FloatImage {
        FloatImage::from_vec(values.len() as u32, 1, values.to_vec()).unwrap()
    }

    #[test]
    fn the_range_draw_depends_on_seed_and_id_only() {
        let a = draw_fraction(0.05, 0.15, 7, "a");
        assert_eq!(a, draw_fraction(0.05, 0.15, 7, "a"));
        assert_ne!(a, draw_fraction(0.05, 0.15, 8, "a"));
        assert_ne!(a, draw_fraction(0.05, 0.15, 7, "b"));
        let draws: Vec<f32> = (0..1000)
            .map(|i| draw_fraction(0.05, 0.15, 1, &i.to_string()))
            .collect();
        assert!(draws.iter().all(|f| (0.05..=0.15).contains(f)));
        let mean = draws.iter().sum::<f32>() / 1000.0;
        assert!((mean - 0.10).abs() < 0.005, "{mean}");
    }

    #[test]
    fn each_scaling_gives_the_rigs_disparity() {
        // Metric: f B / Z.
        let depth = map(&[2.0, 4.0, 8.0, 16.0]);
        let metric = Scaling::Metric {
            focal_px: 100.0,
            baseline_m: 0.5,
        };
        let d = virtual_disparity(&depth, DepthKind::MetricDepth, metric, "x").unwrap();
        assert_eq!(d.map.as_raw(), &[25.0, 12.5, 6.25, 3.125]);
        // Range: inverse depth scaled so its largest is the drawn fraction
        // of the width; the ratios of inverse depth are kept.
        let range = Scaling::Range {
            low: 0.5,
            high: 0.5,
            seed: 0,
        };
        let d = virtual_disparity(&depth, DepthKind::MetricDepth, range, "x").unwrap();
        assert_eq!(d.map.as_raw(), &[2.0, 1.0, 0.5, 0.25]);
        assert_eq!(d.drawn_fraction, Some(0.5));
        // A relative map with negative values is shifted to start at 0.
        let relative = map(&[-1.0, 0.0, 1.0, 3.0]);
        let d = virtual_disparity(&relative, DepthKind::InverseRelative, range, "x").unwrap();
        assert_eq!(d.map.as_raw(), &[0.0, 0.5, 1.0, 2.0]);
        // As is: unchanged; a scaling the kind does not allow is refused.
        let disparity = map(&[1.0, 2.0]);
        let d = virtual_disparity(&disparity, DepthKind::Disparity, Scaling::AsIs, "x").unwrap();
        assert_eq!(d.map, disparity);
        let err = virtual_disparity(&depth, DepthKind::MetricDepth, Scaling::AsIs, "x")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("as-is scaling cannot take a map of kind metric-depth"),
            "{err}"
        );
        let err = virtual_disparity(&map(&[0.0, 1.0]), DepthKind::MetricDepth, metric, "x")
            .unwrap_err()
            .to_string();
        assert!(err.contains("zero or negative depth"), "{err}");
    }

    #[test]
    fn each_camera_is_the_reference_warped_by_its_baselines() {
        let (width, height) = (40, 6);
        let image = RgbImage::from_fn(width, height, |x, y| {
            image::Rgb([(x * 6) as u8, y as u8, 9])
        });
        let disparity = FloatImage::from_fn(width, height, |x, _| {
            image::Luma([if x < 20 { 2.0 } else { 3.0 }])
        });
        let extrapolator = Extrapolator::new(Dilation::None, Box::new(BackgroundFill::default()));
        let layout = ViewLayout::new(5, 2).unwrap();
        let set = extrapolator
            .views_from_one(&image, &disparity, layout)
            .unwrap();
        assert!(set.views[2].is_none());
        for (k, side, steps) in [
            (0, Side::Left, 2.0),
            (1, Side::Left, 1.0),
            (3, Side::Right, 1.0),
            (4, Side::Right, 2.0),
        ] {
            let expected = extrapolator
                .synthesize(&image, &times(&disparity, steps), side, "v")
                .unwrap();
            assert_eq!(set.views[k].as_ref(), Some(&expected), "camera {k}");
        }
        assert!(ViewLayout::new(1, 0).unwrap_err().contains("at least 2"));
        assert!(ViewLayout::new(4, 4).unwrap_err().contains("0 to 3"));
    }
}
