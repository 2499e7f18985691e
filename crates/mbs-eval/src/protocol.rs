//! The named scoring rules of the field (`--protocol`): which ground-truth
//! pixels count and in which regions, what is done to a prediction first,
//! what an outlier is and how the images of a set are combined, for each
//! benchmark as the project a preset is named after does it.
//! docs/evaluation.md tabulates them with the source files and lines each
//! one follows.

use std::fmt;
use std::str::FromStr;

use mbs_dataset::benchmark::{Dataset, UnknownName};

use crate::sums::{DEFAULT_OUT_THRESHOLDS, Metrics, MetricsError};

/// A named set of scoring rules.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Protocol {
    /// mbs's own (conventions §6): every finite ground-truth pixel,
    /// figures per image, averaged per image and pooled over pixels.
    Pixels,
    /// The S3 paper's stereo_toolbox: `0 < gt < 191`, per-image
    /// percentages averaged over the images.
    S3,
    /// RAFT-Stereo's `evaluate_stereo.py`.
    RaftStereo,
    /// IGEV-Stereo's `evaluate_stereo.py`.
    IgevStereo,
    /// The KITTI 2015 (`evaluate_scene_flow.cpp`) and 2012
    /// (`evaluate_stereo.cpp`) devkits.
    Kitti,
    /// ETH3D's two-view evaluator (`src/main.cc`).
    Eth3d,
    /// MiddEval3's `evaldisp.cpp`.
    Middlebury,
}

impl Protocol {
    /// Every protocol, in the order help and docs list them.
    pub const EVERY: [Protocol; 7] = [
        Protocol::Pixels,
        Protocol::S3,
        Protocol::RaftStereo,
        Protocol::IgevStereo,
        Protocol::Kitti,
        Protocol::Eth3d,
        Protocol::Middlebury,
    ];

    /// The name `--protocol` takes.
    pub fn name(self) -> &'static str {
        match self {
            Protocol::Pixels => "pixels",
            Protocol::S3 => "s3",
            Protocol::RaftStereo => "raft-stereo",
            Protocol::IgevStereo => "igev-stereo",
            Protocol::Kitti => "kitti",
            Protocol::Eth3d => "eth3d",
            Protocol::Middlebury => "middlebury",
        }
    }

    /// The code the rules follow.
    pub fn source(self) -> &'static str {
        match self {
            Protocol::Pixels => "mbs conventions §6",
            Protocol::S3 => {
                "stereo_toolbox generalization_eval.py (xxxupeng/stereo_toolbox@6af8685)"
            }
            Protocol::RaftStereo => "evaluate_stereo.py (princeton-vl/RAFT-Stereo@6068c1a)",
            Protocol::IgevStereo => "IGEV-Stereo/evaluate_stereo.py (gangweiX/IGEV@e61a675)",
            Protocol::Kitti => {
                "KITTI devkits: evaluate_scene_flow.cpp (2015), evaluate_stereo.cpp (2012)"
            }
            Protocol::Eth3d => "src/main.cc (ETH3D/two-view-evaluation@42af334)",
            Protocol::Middlebury => "MiddEval3 SDK 1.6 code/evaldisp.cpp",
        }
    }

    /// The data the protocol has rules for.
    pub fn datasets(self) -> &'static [Dataset] {
        use Dataset::*;
        match self {
            Protocol::Pixels | Protocol::S3 => &Dataset::EVERY,
            Protocol::RaftStereo | Protocol::IgevStereo => {
                &[Kitti2015, Kitti2012, Middlebury, Eth3d, SceneFlow]
            }
            Protocol::Kitti => &[Kitti2015, Kitti2012],
            Protocol::Eth3d => &[Eth3d],
            Protocol::Middlebury => &[Middlebury],
        }
    }

    /// The protocol's rules for `dataset`; an error naming the data it has
    /// rules for when `dataset` is not among them.
    pub fn rules(self, dataset: Dataset) -> Result<Rules, ProtocolError> {
        let rules = match self {
            Protocol::Pixels => Some(pixels_rules(dataset)),
            Protocol::S3 => Some(s3_rules(dataset)),
            Protocol::RaftStereo => raft_rules(dataset),
            Protocol::IgevStereo => igev_rules(dataset),
            Protocol::Kitti => kitti_rules(dataset),
            Protocol::Eth3d => (dataset == Dataset::Eth3d).then(eth3d_rules),
            Protocol::Middlebury => (dataset == Dataset::Middlebury).then(middlebury_rules),
        };
        rules.ok_or_else(|| ProtocolError::Undefined {
            protocol: self,
            dataset,
            defined: self
                .datasets()
                .iter()
                .map(|d| d.name())
                .collect::<Vec<_>>()
                .join(", "),
        })
    }
}

impl fmt::Display for Protocol {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Protocol {
    type Err = ProtocolError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Protocol::EVERY
            .into_iter()
            .find(|p| p.name() == text)
            .ok_or_else(|| {
                let names = Protocol::EVERY.map(Protocol::name);
                ProtocolError::Unknown(UnknownName::new(text, "protocol", names))
            })
    }
}

/// Why a protocol cannot score an image.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProtocolError {
    /// No such protocol name (the message lists the protocols there are).
    #[error(transparent)]
    Unknown(UnknownName),
    /// The protocol has no rules for this data.
    #[error("protocol {protocol} has no rules for {dataset}; it scores {defined}")]
    Undefined {
        /// The protocol.
        protocol: Protocol,
        /// The data it was asked to score.
        dataset: Dataset,
        /// The data it has rules for, comma-separated.
        defined: String,
    },
    /// The protocol scores non-occluded pixels, and the ground truth has no
    /// occlusion mask.
    #[error(
        "protocol {protocol} scores the non-occluded pixels of {dataset}, but this ground truth \
         has no occlusion mask (mask0nocc.png)"
    )]
    NeedsMask {
        /// The protocol.
        protocol: Protocol,
        /// The data it scores.
        dataset: Dataset,
    },
    /// A prediction evaldisp cannot bring to the ground truth's size.
    #[error(
        "the prediction is {actual:?} (width, height) and the ground truth {expected:?}: \
         evaldisp takes the ground truth's size or exactly 1/2 or 1/4 of it"
    )]
    Scale {
        /// Size of the ground truth.
        expected: (u32, u32),
        /// Size of the prediction.
        actual: (u32, u32),
    },
    /// The prediction or the mask differ in size from the ground truth.
    #[error(transparent)]
    Size(#[from] MetricsError),
}

/// Which finite ground-truth values a protocol scores (strict bounds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GtRange {
    /// The value must be above this.
    pub above: Option<f32>,
    /// The value (its magnitude, with `magnitude`) must be below this.
    pub below: Option<f32>,
    /// Whether `below` bounds `|gt|` rather than `gt`.
    pub magnitude: bool,
}

impl GtRange {
    /// Every finite value.
    pub const FINITE: GtRange = GtRange {
        above: None,
        below: None,
        magnitude: false,
    };

    /// `above < gt < below`.
    fn between(above: Option<f32>, below: Option<f32>) -> GtRange {
        GtRange {
            above,
            below,
            magnitude: false,
        }
    }

    /// `|gt| < below`.
    fn magnitude_below(below: f32) -> GtRange {
        GtRange {
            above: None,
            below: Some(below),
            magnitude: true,
        }
    }

    /// Whether `gt` is scored.
    pub fn contains(&self, gt: f32) -> bool {
        let bounded = if self.magnitude { gt.abs() } else { gt };
        gt.is_finite()
            && self.above.is_none_or(|a| gt > a)
            && self.below.is_none_or(|b| bounded < b)
    }

    /// The range in words, e.g. `finite, 0 < gt < 191`.
    pub fn describe(&self) -> String {
        let value = if self.magnitude { "|gt|" } else { "gt" };
        match (self.above, self.below) {
            (None, None) => "finite".into(),
            (Some(a), None) => format!("finite, gt > {a}"),
            (None, Some(b)) => format!("finite, {value} < {b}"),
            (Some(a), Some(b)) => format!("finite, {a} < {value} < {b}"),
        }
    }
}

/// Which regions a protocol reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Regions {
    /// ALL, and NOC and OCC (ALL minus NOC) where the ground truth has an
    /// occlusion mask.
    Masked,
    /// ALL only: a mask, if any, is not used.
    AllOnly,
    /// NOC only: the valid pixels inside the non-occluded mask, which the
    /// ground truth must have.
    NocOnly,
}

/// What a protocol does to a prediction before comparing it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PredictionRule {
    /// Compared as it is, at the ground truth's size. A non-finite value
    /// is a missing prediction: an outlier, left out of EPE.
    AsIs,
    /// The KITTI devkits: a value that is not finite or below 0 is a hole,
    /// filled by [`crate::interpolate_background`] before the comparison;
    /// the density counts the values that were there.
    KittiBackground,
    /// ETH3D: a value that is not finite or beyond ± the image width is
    /// not estimated: left out of every figure, it lowers the density
    /// (ETH3D's coverage); with nothing estimated bad-x is 100 %.
    Eth3dEstimated,
    /// MiddEval3's evaldisp: a prediction 2 or 4 times smaller is
    /// upsampled by repeating pixels and multiplied by the factor; values
    /// are clipped to `[0, ndisp]` (`calib.txt`, else 99999 × the factor);
    /// `+inf` and NaN are invalid: counted bad (total-bad), left out of EPE.
    MiddleburyEvaldisp,
}

/// A protocol's headline figure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Figure {
    /// Out-x: share of pixels with error above `x` pixels.
    Out(f32),
    /// KITTI D1: error above 3 px and above 5 % of the ground truth.
    D1,
}

impl Figure {
    /// The name in tables (`Out-3`, `D1`).
    pub fn name(self) -> String {
        match self {
            Figure::Out(x) => format!("Out-{x}"),
            Figure::D1 => "D1".into(),
        }
    }

    /// The key in JSON (`out3`, `d1`).
    pub fn key(self) -> String {
        match self {
            Figure::Out(x) => format!("out{x}"),
            Figure::D1 => "d1".into(),
        }
    }

    /// The figure's value in `metrics`.
    pub fn of(self, metrics: &Metrics) -> Option<f64> {
        match self {
            Figure::Out(x) => metrics.out(x),
            Figure::D1 => metrics.d1,
        }
    }
}

/// How the images of a set are combined into one figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Aggregation {
    /// Each image's figure, then their mean over the images where the
    /// region has pixels.
    PerImage,
    /// Counts and sums over every pixel of every image, then the figure.
    Pooled,
}

impl Aggregation {
    fn describe(self) -> &'static str {
        match self {
            Aggregation::PerImage => "mean over images",
            Aggregation::Pooled => "pooled over pixels",
        }
    }
}

/// A protocol's rules for one dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct Rules {
    /// The protocol.
    pub protocol: Protocol,
    /// The data.
    pub dataset: Dataset,
    /// Which ground-truth values are scored.
    pub valid: GtRange,
    /// Which regions are reported.
    pub regions: Regions,
    /// What is done to the prediction first.
    pub prediction: PredictionRule,
    /// The Out-x thresholds computed (pixels; strict `>`).
    pub thresholds: Vec<f32>,
    /// The figure the benchmark reports.
    pub headline: Figure,
    /// Whether KITTI's D1 is one of the figures.
    pub d1: bool,
    /// How Out-x, D1 and the density are combined over images.
    pub outliers: Aggregation,
    /// How the EPE is combined over images; `None`: not a figure.
    pub epe: Option<Aggregation>,
}

impl Rules {
    /// Rules scoring `valid` as they are over ALL, NOC and OCC at
    /// `thresholds` (headline Out-first), per image, then averaged.
    fn new(protocol: Protocol, dataset: Dataset, valid: GtRange, thresholds: &[f32]) -> Rules {
        Rules {
            protocol,
            dataset,
            valid,
            regions: Regions::Masked,
            prediction: PredictionRule::AsIs,
            thresholds: thresholds.to_vec(),
            headline: Figure::Out(thresholds[0]),
            d1: false,
            outliers: Aggregation::PerImage,
            epe: Some(Aggregation::PerImage),
        }
    }

    /// The same rules at other Out-x thresholds, the headline being Out-x
    /// of the first (`--threshold`, `--thresholds`); none: unchanged.
    pub fn with_thresholds(mut self, thresholds: &[f32]) -> Rules {
        if let Some(&first) = thresholds.first() {
            self.thresholds = thresholds.to_vec();
            self.headline = Figure::Out(first);
        }
        self
    }

    /// The rules in one line, for tables and JSON.
    pub fn describe(&self) -> String {
        let regions = match self.regions {
            Regions::Masked => "ALL, NOC, OCC",
            Regions::AllOnly => "ALL",
            Regions::NocOnly => "NOC",
        };
        let prediction = match self.prediction {
            PredictionRule::AsIs => "as is, non-finite = outlier left out of EPE",
            PredictionRule::KittiBackground => "holes filled by interpolateBackground",
            PredictionRule::Eth3dEstimated => "non-finite or |d| > width not estimated",
            PredictionRule::MiddleburyEvaldisp => {
                "upsampled x1/2/4, clipped to [0, ndisp], +inf/NaN bad"
            }
        };
        let thresholds: Vec<String> = self.thresholds.iter().map(f32::to_string).collect();
        let mut outlier = format!("Out-x |d - gt| > x px (x = {})", thresholds.join(", "));
        if self.d1 {
            outlier += ", D1 > 3 px and > 5 % of gt";
        }
        let epe = self
            .epe
            .map_or("none".to_string(), |a| a.describe().to_string());
        format!(
            "{} on {}: GT {}; regions {regions}; prediction {prediction}; {outlier}, {}; \
             headline {}; EPE {epe}",
            self.protocol,
            self.dataset.name(),
            self.valid.describe(),
            self.outliers.describe(),
            self.headline.name()
        )
    }
}

/// `protocol`'s rules for `dataset` at `thresholds` (the headline Out-x
/// of the first), or when none is given at Out-1, 2, 3 under `pixels` and
/// the protocol's own otherwise: `eval`'s `--protocol` and `--thresholds`.
pub fn rules_for(
    protocol: Protocol,
    dataset: Dataset,
    thresholds: &[f32],
) -> Result<Rules, ProtocolError> {
    let rules = protocol.rules(dataset)?;
    Ok(match (thresholds.is_empty(), protocol) {
        (false, _) => rules.with_thresholds(thresholds),
        (true, Protocol::Pixels) => rules.with_thresholds(&DEFAULT_OUT_THRESHOLDS),
        (true, _) => rules,
    })
}

/// The Out-x threshold (pixels) `dataset` is customarily reported with
/// (the S3 paper's Table 4); `None` for other data.
fn customary_threshold(dataset: Dataset) -> Option<f32> {
    match dataset {
        Dataset::Kitti2015 | Dataset::Kitti2012 | Dataset::DrivingStereo => Some(3.0),
        Dataset::Middlebury => Some(2.0),
        Dataset::Eth3d | Dataset::SceneFlow => Some(1.0),
        Dataset::Other => None,
    }
}

/// The threshold of `dataset`, or Out-1, 2, 3 for other data.
fn customary(dataset: Dataset) -> Vec<f32> {
    customary_threshold(dataset).map_or(DEFAULT_OUT_THRESHOLDS.to_vec(), |x| vec![x])
}

/// mbs's own: finite ground truth, as is, pooled over pixels.
fn pixels_rules(dataset: Dataset) -> Rules {
    Rules {
        d1: true,
        outliers: Aggregation::Pooled,
        epe: Some(Aggregation::Pooled),
        ..Rules::new(
            Protocol::Pixels,
            dataset,
            GtRange::FINITE,
            &customary(dataset),
        )
    }
}

/// stereo_toolbox (generalization_eval.py:32-58,
/// drivingstereo_weather_test.py:34-49): `0 < gt < maxdisp - 1 = 191`.
fn s3_rules(dataset: Dataset) -> Rules {
    let valid = GtRange::between(Some(0.0), Some(191.0));
    Rules::new(Protocol::S3, dataset, valid, &customary(dataset))
}

/// RAFT-Stereo's evaluate_stereo.py: ALL pixels (the Middlebury mask is
/// read but `valid >= -0.5` keeps every pixel); KITTI and FlyingThings
/// pool Out-x over pixels.
fn raft_rules(dataset: Dataset) -> Option<Rules> {
    let (valid, pooled) = match dataset {
        Dataset::Kitti2015 | Dataset::Kitti2012 => (GtRange::between(Some(0.0), None), true),
        Dataset::Eth3d => (GtRange::magnitude_below(512.0), false),
        Dataset::Middlebury => (GtRange::between(None, Some(1000.0)), false),
        Dataset::SceneFlow => (GtRange::magnitude_below(192.0), true),
        Dataset::DrivingStereo | Dataset::Other => return None,
    };
    Some(network_rules(Protocol::RaftStereo, dataset, valid, pooled))
}

/// IGEV-Stereo's evaluate_stereo.py: KITTI 2012 and 2015 `0 < gt < 192`
/// pooled; ETH3D and Middlebury NOC only (Middlebury `gt < 192`, ETH3D no
/// cap); SceneFlow `|gt| < 192` at Out-3, pooled.
fn igev_rules(dataset: Dataset) -> Option<Rules> {
    let (valid, pooled, regions) = match dataset {
        Dataset::Kitti2015 | Dataset::Kitti2012 => (
            GtRange::between(Some(0.0), Some(192.0)),
            true,
            Regions::AllOnly,
        ),
        Dataset::Eth3d => (GtRange::between(None, Some(512.0)), false, Regions::NocOnly),
        Dataset::Middlebury => (GtRange::between(None, Some(192.0)), false, Regions::NocOnly),
        Dataset::SceneFlow => (GtRange::magnitude_below(192.0), true, Regions::AllOnly),
        Dataset::DrivingStereo | Dataset::Other => return None,
    };
    let rules = network_rules(Protocol::IgevStereo, dataset, valid, pooled);
    let rules = match dataset {
        Dataset::SceneFlow => rules.with_thresholds(&[3.0]),
        _ => rules,
    };
    Some(Rules { regions, ..rules })
}

/// The networks' scripts: ALL, the customary threshold, EPE per image,
/// Out-x per image or `pooled`.
fn network_rules(protocol: Protocol, dataset: Dataset, valid: GtRange, pooled: bool) -> Rules {
    Rules {
        regions: Regions::AllOnly,
        outliers: if pooled {
            Aggregation::Pooled
        } else {
            Aggregation::PerImage
        },
        ..Rules::new(protocol, dataset, valid, &customary(dataset))
    }
}

/// The KITTI devkits: holes filled from the background; 2015 D1 pooled
/// over the images, no EPE; 2012 Out-1..5 per image, averaged, headline
/// Out-3, EPE (Avg-All) per image.
fn kitti_rules(dataset: Dataset) -> Option<Rules> {
    let rules = Rules {
        prediction: PredictionRule::KittiBackground,
        ..Rules::new(Protocol::Kitti, dataset, GtRange::FINITE, &[3.0])
    };
    match dataset {
        Dataset::Kitti2015 => Some(Rules {
            headline: Figure::D1,
            d1: true,
            outliers: Aggregation::Pooled,
            epe: None,
            ..rules
        }),
        Dataset::Kitti2012 => Some(Rules {
            thresholds: vec![1.0, 2.0, 3.0, 4.0, 5.0],
            ..rules
        }),
        _ => None,
    }
}

/// ETH3D's evaluator: bad-0.5/1/2/4 and avgerr over the estimated pixels
/// of each image, averaged over the images; headline bad-1.0.
fn eth3d_rules() -> Rules {
    Rules {
        prediction: PredictionRule::Eth3dEstimated,
        headline: Figure::Out(1.0),
        ..Rules::new(
            Protocol::Eth3d,
            Dataset::Eth3d,
            GtRange::FINITE,
            &[0.5, 1.0, 2.0, 4.0],
        )
    }
}

/// MiddEval3's evaldisp: total-bad at 0.5, 1, 2, 4 px per image, averaged
/// over the images; headline bad-2.0.
fn middlebury_rules() -> Rules {
    Rules {
        prediction: PredictionRule::MiddleburyEvaldisp,
        headline: Figure::Out(2.0),
        ..Rules::new(
            Protocol::Middlebury,
            Dataset::Middlebury,
            GtRange::FINITE,
            &[0.5, 1.0, 2.0, 4.0],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_and_unknown_names_list_the_protocols() {
        for protocol in Protocol::EVERY {
            assert_eq!(protocol.name().parse::<Protocol>(), Ok(protocol));
        }
        let err = "S3".parse::<Protocol>().unwrap_err().to_string();
        assert!(err.contains("`S3` is not a protocol: pixels, s3"), "{err}");
    }

    #[test]
    fn each_protocol_has_rules_exactly_for_its_datasets() {
        for protocol in Protocol::EVERY {
            for dataset in Dataset::EVERY {
                let rules = protocol.rules(dataset);
                assert_eq!(
                    rules.is_ok(),
                    protocol.datasets().contains(&dataset),
                    "{protocol} on {dataset:?}"
                );
                if let Ok(rules) = rules {
                    assert_eq!((rules.protocol, rules.dataset), (protocol, dataset));
                    assert!(rules.describe().starts_with(protocol.name()));
                }
            }
        }
        let err = Protocol::Middlebury.rules(Dataset::Eth3d).unwrap_err();
        assert_eq!(
            err.to_string(),
            "protocol middlebury has no rules for ETH3D; it scores Middlebury"
        );
    }

    #[test]
    fn ranges_are_strict_and_bound_the_magnitude_when_asked() {
        let s3 = GtRange::between(Some(0.0), Some(191.0));
        assert!(s3.contains(190.9) && !s3.contains(191.0) && !s3.contains(0.0));
        assert!(!s3.contains(f32::INFINITY) && !s3.contains(f32::NAN));
        let flying = GtRange::magnitude_below(192.0);
        assert!(flying.contains(-191.0) && !flying.contains(-192.0));
        assert!(GtRange::FINITE.contains(-5.0) && !GtRange::FINITE.contains(f32::INFINITY));
        assert_eq!(s3.describe(), "finite, 0 < gt < 191");
        assert_eq!(flying.describe(), "finite, |gt| < 192");
    }

    #[test]
    fn thresholds_follow_each_benchmark_and_can_be_overridden() {
        let headline = |p: Protocol, d: Dataset| p.rules(d).unwrap().headline;
        assert_eq!(headline(Protocol::S3, Dataset::Kitti2012), Figure::Out(3.0));
        assert_eq!(
            headline(Protocol::S3, Dataset::Middlebury),
            Figure::Out(2.0)
        );
        assert_eq!(headline(Protocol::S3, Dataset::Eth3d), Figure::Out(1.0));
        assert_eq!(
            headline(Protocol::S3, Dataset::DrivingStereo),
            Figure::Out(3.0)
        );
        assert_eq!(headline(Protocol::Kitti, Dataset::Kitti2015), Figure::D1);
        assert_eq!(
            headline(Protocol::Kitti, Dataset::Kitti2012),
            Figure::Out(3.0)
        );
        assert_eq!(
            headline(Protocol::IgevStereo, Dataset::SceneFlow),
            Figure::Out(3.0)
        );
        assert_eq!(
            headline(Protocol::RaftStereo, Dataset::SceneFlow),
            Figure::Out(1.0)
        );
        let rules = Protocol::Kitti
            .rules(Dataset::Kitti2015)
            .unwrap()
            .with_thresholds(&[2.5]);
        assert_eq!(
            (rules.headline, rules.thresholds),
            (Figure::Out(2.5), vec![2.5])
        );
        assert_eq!(Figure::Out(0.5).key(), "out0.5");
    }

    #[test]
    fn rules_for_takes_the_thresholds_given_else_eval_s_defaults() {
        let pixels = rules_for(Protocol::Pixels, Dataset::Kitti2015, &[]).unwrap();
        assert_eq!(pixels.thresholds, DEFAULT_OUT_THRESHOLDS);
        let s3 = rules_for(Protocol::S3, Dataset::Kitti2015, &[]).unwrap();
        assert_eq!(s3, Protocol::S3.rules(Dataset::Kitti2015).unwrap());
        let given = rules_for(Protocol::S3, Dataset::Eth3d, &[0.5, 2.0]).unwrap();
        assert_eq!(
            (given.headline, given.thresholds),
            (Figure::Out(0.5), vec![0.5, 2.0])
        );
        assert!(rules_for(Protocol::Kitti, Dataset::Other, &[]).is_err());
    }
}
