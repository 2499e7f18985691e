//! Scores of a set of images: per image, averaged per image, and pooled
//! over pixels (conventions §6), as a text table or JSON: the `pixels`
//! protocol's report, which [`crate::ProtocolReport`] renders through it.

use serde_json::{Value, json};

use crate::sums::{MeanMetrics, Metrics, Region, RegionSums};

/// Per-image sums with their per-image means and pixel-pooled totals.
pub(crate) struct MetricsReport {
    images: Vec<(String, RegionSums)>,
    pooled: RegionSums,
}

impl MetricsReport {
    /// Pools the images' sums.
    pub(crate) fn new(images: Vec<(String, RegionSums)>) -> Self {
        let mut pooled = RegionSums::default();
        for (_, sums) in &images {
            pooled.merge(sums);
        }
        Self { pooled, images }
    }

    /// Per-image mean of `region` (images without the region are left out).
    fn mean(&self, region: Region) -> Option<Metrics> {
        let mut mean = MeanMetrics::new();
        for (_, sums) in &self.images {
            if let Some(s) = sums.get(region) {
                mean.add(&s.metrics());
            }
        }
        (mean.images() > 0).then(|| mean.mean())
    }

    /// The report as JSON: per image, mean over images and pooled, per region.
    pub(crate) fn json(&self) -> Value {
        let regions = |get: &dyn Fn(Region) -> Option<Metrics>| {
            let mut map = serde_json::Map::new();
            for region in Region::EVERY {
                if let Some(m) = get(region) {
                    map.insert(region.name().into(), metrics_json(&m));
                }
            }
            Value::Object(map)
        };
        json!({
            "images": self.images.iter().map(|(name, sums)| {
                let mut v = regions(&|r| sums.get(r).map(|s| s.metrics()));
                v["name"] = json!(name);
                v
            }).collect::<Vec<_>>(),
            "mean": regions(&|r| self.mean(r)),
            "pooled": regions(&|r| self.pooled.get(r).map(|s| s.metrics())),
        })
    }

    /// The report as a text table.
    pub(crate) fn table(&self, thresholds: &[f32]) -> String {
        let count = self.images.len();
        let mean_label = format!("mean of {count} images");
        let width = self
            .images
            .iter()
            .map(|(name, _)| name.len())
            .chain([mean_label.len()])
            .max()
            .unwrap_or(0);
        let mut head = format!(
            "{:<width$} {:<4} {:>10} {:>8}",
            "image", "set", "pixels", "EPE"
        );
        for x in thresholds {
            head += &format!(" {:>8}", format!("Out-{x}"));
        }
        head += &format!(" {:>8} {:>8}\n", "D1", "density");
        let mut out = head;
        let mut row = |name: &str, region: Region, m: &Metrics, pixels: String| {
            let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}%"));
            out += &format!(
                "{:<width$} {:<4} {:>10} {:>8}",
                name,
                region.name(),
                pixels,
                m.epe.map_or("-".to_string(), |v| format!("{v:.3}"))
            );
            for &x in thresholds {
                out += &format!(" {:>8}", pct(m.out(x)));
            }
            out += &format!(" {:>8} {:>8}\n", pct(m.d1), pct(m.density));
        };
        for (name, sums) in &self.images {
            for region in Region::EVERY {
                if let Some(s) = sums.get(region) {
                    let m = s.metrics();
                    row(name, region, &m, m.pixels.to_string());
                }
            }
        }
        for region in Region::EVERY {
            if let Some(m) = self.mean(region) {
                row(&mean_label, region, &m, "-".into());
            }
        }
        for region in Region::EVERY {
            if let Some(s) = self.pooled.get(region) {
                let m = s.metrics();
                row("pooled", region, &m, m.pixels.to_string());
            }
        }
        out
    }
}

/// One region's metrics as JSON: pixels, epe, d1, density and out<x>.
pub(crate) fn metrics_json(m: &Metrics) -> Value {
    let mut v = json!({
        "pixels": m.pixels,
        "epe": m.epe,
        "d1": m.d1,
        "density": m.density,
    });
    for &(x, value) in &m.out {
        v[format!("out{x}")] = json!(value);
    }
    v
}

#[cfg(test)]
mod tests {
    use mbs_core::FloatImage;

    use super::*;
    use crate::sums::evaluate;

    #[test]
    fn mean_weighs_images_and_pooled_weighs_pixels() {
        // Image a: 1 pixel off by 4; image b: 3 pixels exact.
        let a = evaluate(
            &FloatImage::from_raw(1, 1, vec![5.0]).unwrap(),
            &FloatImage::from_raw(1, 1, vec![1.0]).unwrap(),
            None,
            &[3.0],
        )
        .unwrap();
        let b = evaluate(
            &FloatImage::from_raw(3, 1, vec![2.0; 3]).unwrap(),
            &FloatImage::from_raw(3, 1, vec![2.0; 3]).unwrap(),
            None,
            &[3.0],
        )
        .unwrap();
        let report = MetricsReport::new(vec![("a".into(), a), ("b".into(), b)]);
        assert_eq!(report.images.len(), 2);
        let mean = report.mean(Region::All).unwrap();
        assert_eq!(mean.epe, Some(2.0));
        assert_eq!(mean.out(3.0), Some(50.0));
        let pooled = report.pooled.all.metrics();
        assert_eq!(pooled.epe, Some(1.0));
        assert_eq!(pooled.out(3.0), Some(25.0));
        let json = report.json();
        assert_eq!(json["mean"]["ALL"]["epe"], 2.0);
        assert_eq!(json["pooled"]["ALL"]["out3"], 25.0);
        assert_eq!(json["images"][1]["name"], "b");
        let table = report.table(&[3.0]);
        assert!(table.contains("mean of 2 images ALL"), "{table}");
        assert!(
            table
                .lines()
                .any(|l| l.starts_with("pooled") && l.contains("25.00%")),
            "{table}"
        );
    }
}
