//! A set of images scored under one protocol: each image's figures and the
//! set's, combined as the protocol combines them, as a text table or JSON.
//! Under `pixels` it is the pooled and per-image report of
//! conventions §6 (`report.rs`), with the protocol named.

use serde_json::{Value, json};

use crate::protocol::{Protocol, Rules};
use crate::report::{MetricsReport, metrics_json};
use crate::score::{ImageScore, Summary};
use crate::sums::{Metrics, Region};

/// Images scored under one protocol's rules.
#[derive(Debug, Clone, PartialEq)]
pub struct ProtocolReport {
    rules: Rules,
    images: Vec<(String, ImageScore)>,
}

impl ProtocolReport {
    /// A report of `images` (name and score) scored under `rules`.
    pub fn new(rules: Rules, images: Vec<(String, ImageScore)>) -> Self {
        Self { rules, images }
    }

    /// The rules the images were scored under.
    pub fn rules(&self) -> &Rules {
        &self.rules
    }

    /// The number of images.
    pub fn images(&self) -> usize {
        self.images.len()
    }

    /// The set's figures in `region`, if any image has pixels there.
    pub fn summary(&self, region: Region) -> Option<Summary> {
        self.rules
            .summarise(self.images.iter().filter_map(|(_, s)| s.get(region)))
    }

    /// The protocol's headline figure (percent) in `region`.
    pub fn headline(&self, region: Region) -> Option<f64> {
        self.rules.headline.of(&self.summary(region)?.metrics)
    }

    /// The set's EPE in its first region (ALL, or NOC where the protocol
    /// scores NOC only).
    pub fn epe(&self) -> Option<f64> {
        Region::EVERY
            .into_iter()
            .find_map(|r| self.summary(r))?
            .metrics
            .epe
    }

    /// The `pixels` protocol's report of the same images.
    fn pixels_report(&self) -> MetricsReport {
        MetricsReport::new(
            self.images
                .iter()
                .map(|(name, score)| (name.clone(), score.region_sums()))
                .collect(),
        )
    }

    /// The report as JSON: the protocol and its rules, each image's
    /// figures and the set's (`pixels`: per image, their mean and pooled,
    /// with the protocol named).
    pub fn json(&self) -> Value {
        if self.rules.protocol == Protocol::Pixels {
            let mut value = self.pixels_report().json();
            value["protocol"] = json!(Protocol::Pixels.name());
            return value;
        }
        let regions = |get: &dyn Fn(Region) -> Option<Value>| {
            let mut map = serde_json::Map::new();
            for region in Region::EVERY {
                if let Some(v) = get(region) {
                    map.insert(region.name().into(), v);
                }
            }
            Value::Object(map)
        };
        let images: Vec<Value> = self
            .images
            .iter()
            .map(|(name, score)| {
                let mut v =
                    regions(&|r| score.get(r).map(|t| metrics_json(&self.rules.metrics(t))));
                v["name"] = json!(name);
                v
            })
            .collect();
        json!({
            "protocol": self.rules.protocol.name(),
            "dataset": self.rules.dataset.name(),
            "rules": self.rules.describe(),
            "headline": self.rules.headline.key(),
            "images": images,
            "score": regions(&|r| {
                let summary = self.summary(r)?;
                let mut v = metrics_json(&summary.metrics);
                v["images"] = json!(summary.images);
                Some(v)
            }),
        })
    }

    /// The report as a text table after a line naming the protocol and its
    /// rules (`pixels`: per image, their mean and pooled, at the rules'
    /// thresholds).
    pub fn table(&self) -> String {
        let head = format!("protocol {}\n", self.rules.describe());
        if self.rules.protocol == Protocol::Pixels {
            return head + &self.pixels_report().table(&self.rules.thresholds);
        }
        let label = format!("{}, {} images", self.rules.protocol, self.images.len());
        let width = self
            .images
            .iter()
            .map(|(name, _)| name.len())
            .chain([label.len(), 5])
            .max()
            .unwrap_or(0);
        let mut out = head + &self.header(width);
        for (name, score) in &self.images {
            for (region, tally) in &score.regions {
                let m = self.rules.metrics(tally);
                out += &self.row(width, name, *region, &m);
            }
        }
        for region in Region::EVERY {
            if let Some(summary) = self.summary(region) {
                out += &self.row(width, &label, region, &summary.metrics);
            }
        }
        out
    }

    /// The table's header line.
    fn header(&self, width: usize) -> String {
        let mut line = format!(
            "{:<width$} {:<4} {:>10} {:>8}",
            "image", "set", "pixels", "EPE"
        );
        for x in &self.rules.thresholds {
            line += &format!(" {:>8}", format!("Out-{x}"));
        }
        if self.rules.d1 {
            line += &format!(" {:>8}", "D1");
        }
        line + &format!(" {:>8}\n", "density")
    }

    /// One line of the table: `name`'s figures `m` in `region`.
    fn row(&self, width: usize, name: &str, region: Region, m: &Metrics) -> String {
        let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}%"));
        let epe = m.epe.map_or("-".to_string(), |v| format!("{v:.3}"));
        let mut line = format!(
            "{name:<width$} {:<4} {:>10} {epe:>8}",
            region.name(),
            m.pixels
        );
        for &x in &self.rules.thresholds {
            line += &format!(" {:>8}", pct(m.out(x)));
        }
        if self.rules.d1 {
            line += &format!(" {:>8}", pct(m.d1));
        }
        line + &format!(" {:>8}\n", pct(m.density))
    }
}

#[cfg(test)]
mod tests {
    use mbs_core::FloatImage;
    use mbs_dataset::benchmark::Dataset;

    use super::*;
    use crate::score::Frame;

    fn report(protocol: Protocol) -> ProtocolReport {
        let rules = protocol.rules(Dataset::DrivingStereo).unwrap();
        // Image a: one pixel off by 4; image b: three exact pixels.
        let images = [
            ("a", vec![5.0], vec![1.0]),
            ("b", vec![2.0; 3], vec![2.0; 3]),
        ]
        .into_iter()
        .map(|(name, pred, gt)| {
            let n = pred.len() as u32;
            let frame = Frame {
                prediction: &FloatImage::from_raw(n, 1, pred).unwrap(),
                gt: &FloatImage::from_raw(n, 1, gt).unwrap(),
                noc: None,
                disparity_bound: None,
            };
            (name.to_string(), rules.score(&frame).unwrap())
        })
        .collect();
        ProtocolReport::new(rules, images)
    }

    #[test]
    fn s3_averages_images_and_pixels_pools_them() {
        let s3 = report(Protocol::S3);
        assert_eq!(s3.headline(Region::All), Some(50.0));
        assert_eq!(s3.epe(), Some(2.0));
        let json = s3.json();
        assert_eq!(json["protocol"], "s3");
        assert_eq!(json["score"]["ALL"]["out3"], 50.0);
        assert_eq!(json["score"]["ALL"]["images"], 2);
        assert_eq!(json["images"][0]["ALL"]["epe"], 4.0);
        let table = s3.table();
        assert!(table.starts_with("protocol s3 on DrivingStereo"), "{table}");
        assert!(
            table
                .lines()
                .any(|l| l.starts_with("s3, 2 images ALL") && l.contains("50.00%")),
            "{table}"
        );

        let pixels = report(Protocol::Pixels);
        assert_eq!(pixels.headline(Region::All), Some(25.0));
        assert_eq!(pixels.epe(), Some(1.0));
        assert_eq!(pixels.json()["pooled"]["ALL"]["out3"], 25.0);
        assert_eq!(pixels.json()["protocol"], "pixels");
        assert!(pixels.table().contains("mean of 2 images ALL"));
        assert_eq!(s3.headline(Region::Noc), None);
    }
}
