//! Monocular depth: what a map holds ([`DepthKind`]), the checks a map
//! must pass before it becomes a disparity, whoever computed it (an ONNX
//! network, a file, a Python caller's own network), and the trait of the
//! networks that compute one ([`DepthEstimator`]).

use mbs_core::{FloatImage, RgbImage};
use serde::{Deserialize, Serialize};

/// A depth network's map of one image.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthMap {
    /// The map on the image's grid: every value finite, and as its kind
    /// allows ([`DepthKind::problem`]).
    pub values: FloatImage,
    /// What the values are.
    pub kind: DepthKind,
}

/// A monocular depth network: one image in, its [`DepthMap`] out.
pub trait DepthEstimator: Send + Sync {
    /// The map of `image`; an error names the network.
    fn estimate(&self, image: &RgbImage) -> crate::error::Result<DepthMap>;
}

/// What a monocular depth map holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DepthKind {
    /// Depth in metres: FastDepth, metric Depth Anything.
    MetricDepth,
    /// Inverse depth up to an unknown scale and shift (an affine-invariant
    /// disparity): relative Depth Anything, MiDaS.
    InverseRelative,
    /// Disparity in pixels of the image it was computed for.
    Disparity,
}

impl DepthKind {
    /// Every kind, in the order of their names in messages.
    pub const EVERY: [DepthKind; 3] = [
        DepthKind::MetricDepth,
        DepthKind::InverseRelative,
        DepthKind::Disparity,
    ];

    /// The kind's name in cards, flags and manifests.
    pub fn key(self) -> &'static str {
        match self {
            DepthKind::MetricDepth => "metric-depth",
            DepthKind::InverseRelative => "inverse-relative",
            DepthKind::Disparity => "disparity",
        }
    }

    /// Why `map` cannot hold values of this kind, or `None` if it can: a
    /// NaN or infinite value (for any kind), a depth of zero or below (for
    /// metric depth), a negative disparity, or a map with one value only
    /// (no depth order to draw views from).
    pub fn problem(self, map: &FloatImage) -> Option<String> {
        let count = map.len();
        let bad = map.iter().filter(|v| !v.is_finite()).count();
        if bad > 0 {
            return Some(format!(
                "{bad} of {count} values are NaN or infinite: not a depth map"
            ));
        }
        let (what, refused): (&str, fn(f32) -> bool) = match self {
            DepthKind::MetricDepth => ("zero or negative depth", |v| v <= 0.0),
            DepthKind::Disparity => ("negative disparity", |v| v < 0.0),
            DepthKind::InverseRelative => ("", |_| false),
        };
        let rejected = map.iter().filter(|&&v| refused(v)).count();
        if rejected > 0 {
            let hint = match self {
                DepthKind::MetricDepth => {
                    ": a relative model? its kind is inverse-relative, not metric-depth"
                }
                _ => "",
            };
            return Some(format!(
                "{rejected} of {count} values are a {what} for a map of kind {}{hint}",
                self.key()
            ));
        }
        let first = map.iter().next().copied().unwrap_or_default();
        if map.iter().all(|&v| v == first) {
            return Some(format!(
                "every value is {first}: a constant map has no depth to draw views from"
            ));
        }
        None
    }
}

impl std::fmt::Display for DepthKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

impl std::str::FromStr for DepthKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        DepthKind::EVERY
            .into_iter()
            .find(|kind| kind.key() == s)
            .ok_or_else(|| {
                format!(
                    "unknown depth kind {s:?}: expected metric-depth, inverse-relative or disparity"
                )
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(values: &[f32]) -> FloatImage {
        FloatImage::from_vec(values.len() as u32, 1, values.to_vec()).unwrap()
    }

    #[test]
    fn each_kind_refuses_what_it_cannot_hold() {
        assert_eq!(DepthKind::MetricDepth.problem(&map(&[1.0, 2.0])), None);
        let zero = DepthKind::MetricDepth.problem(&map(&[0.0, 2.0])).unwrap();
        assert!(
            zero.starts_with("1 of 2 values are a zero or negative depth"),
            "{zero}"
        );
        assert!(zero.contains("inverse-relative"), "{zero}");
        let nan = DepthKind::InverseRelative
            .problem(&map(&[f32::NAN, 2.0]))
            .unwrap();
        assert!(
            nan.starts_with("1 of 2 values are NaN or infinite"),
            "{nan}"
        );
        assert_eq!(DepthKind::InverseRelative.problem(&map(&[-1.0, 2.0])), None);
        let negative = DepthKind::Disparity.problem(&map(&[-1.0, 2.0])).unwrap();
        assert!(negative.contains("negative disparity"), "{negative}");
        let constant = DepthKind::Disparity.problem(&map(&[3.0, 3.0])).unwrap();
        assert!(constant.starts_with("every value is 3"), "{constant}");
    }

    #[test]
    fn names_round_trip() {
        for kind in DepthKind::EVERY {
            assert_eq!(kind.key().parse::<DepthKind>(), Ok(kind));
            assert_eq!(serde_json::to_string(&kind).unwrap(), format!("\"{kind}\""));
        }
        assert!(
            "metric"
                .parse::<DepthKind>()
                .unwrap_err()
                .contains("metric-depth")
        );
    }
}
