//! The validation-level watch of a run: a teacher that got worse after its
//! best validation and stayed worse, or whose disparities reach far less
//! than the ground truth's (the drift of issue 61: an IGEV-Stereo teacher
//! shrinking toward small disparities while its masks stay full, which
//! [`crate::supervision::CollapseWatch`] cannot see). It also tells the run
//! when a validation is the best so far, so that the run keeps that
//! teacher (`checkpoints/best/`, [`crate::checkpoint::save_best`]).

use serde_json::Value;

use crate::data::validation::{DisparityRange, RANGE_PERCENTILE};

/// Percentage points of held-out Out-3 ALL above its best at which a
/// validation counts as worse.
pub const DRIFT_POINTS: f64 = 5.0;
/// The stretch, as a share of the run's steps, that a worse validation
/// must lie after the best before [`DriftWatch`] warns.
pub const DRIFT_STRETCH: f64 = 0.1;
/// The share of the ground truth's range below which the teacher's range
/// counts as shrunk.
pub const RANGE_SHARE: f32 = 0.5;

/// The best validation so far.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Best {
    /// Steps taken when it was scored.
    pub step: usize,
    /// Its held-out Out-3 ALL (%).
    pub out3: f64,
}

/// What one validation told the watch.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Verdict {
    /// The validation is the best so far (after step 0).
    pub best: bool,
    /// Warnings for the log (each once, until the run recovers).
    pub warnings: Vec<String>,
}

/// Watches a run's validations; see the module's documentation.
#[derive(Debug, Clone, PartialEq)]
pub struct DriftWatch {
    best: Option<Best>,
    /// Steps a worse validation must lie after the best.
    stretch: usize,
    warned_drift: bool,
    warned_range: bool,
}

impl DriftWatch {
    /// A watch for a run of `total_steps`.
    pub fn new(total_steps: usize) -> Self {
        Self {
            best: None,
            stretch: ((DRIFT_STRETCH * total_steps as f64).round() as usize).max(1),
            warned_drift: false,
            warned_range: false,
        }
    }

    /// The watch of a resumed run: [`DriftWatch::new`] with the best of the
    /// validations `val.jsonl` kept (`lines`), without warning again.
    pub fn resumed(total_steps: usize, lines: &[Value]) -> Self {
        let mut watch = Self::new(total_steps);
        for line in lines {
            let step = line["step"].as_u64().map(|s| s as usize);
            if let (Some(step), Some(out3)) = (step, line["ALL"]["out3"].as_f64()) {
                watch.score(step, out3);
            }
        }
        watch
    }

    /// The best validation so far (after step 0).
    pub fn best(&self) -> Option<Best> {
        self.best
    }

    /// Records a validation at `step` with held-out Out-3 ALL `out3`;
    /// returns whether it is the best so far (step 0, the untrained
    /// network, never is).
    fn score(&mut self, step: usize, out3: f64) -> bool {
        if step == 0 || self.best.is_some_and(|b| out3 >= b.out3) {
            return false;
        }
        self.best = Some(Best { step, out3 });
        self.warned_drift = false;
        true
    }

    /// Takes the validation at `step`: its Out-3 ALL (%) and how far the
    /// teacher's disparities and the ground truth's reach.
    pub fn observe(&mut self, step: usize, out3: f64, range: Option<DisparityRange>) -> Verdict {
        let best = self.score(step, out3);
        let mut warnings = Vec::new();
        if let Some(message) = self.drift(step, out3) {
            warnings.push(message);
        }
        if let Some(message) = self.shrunk(step, range) {
            warnings.push(message);
        }
        Verdict { best, warnings }
    }

    /// The warning when `out3` is more than [`DRIFT_POINTS`] worse than
    /// the best and at least the stretch after it.
    fn drift(&mut self, step: usize, out3: f64) -> Option<String> {
        let best = self.best?;
        let worse = out3 > best.out3 + DRIFT_POINTS && step >= best.step + self.stretch;
        if !worse || self.warned_drift {
            return None;
        }
        self.warned_drift = true;
        Some(format!(
            "step {step}: held-out Out-3 ALL is {out3:.1} %, {:.1} points worse than its best \
             ({:.1} % at step {}) {} steps later: the teacher is drifting; the best teacher is \
             kept in checkpoints/best/ (docs/training.md, \"A teacher that drifts\")",
            out3 - best.out3,
            best.out3,
            best.step,
            step - best.step
        ))
    }

    /// The warning when the teacher's range falls below [`RANGE_SHARE`] of
    /// the ground truth's (after step 0; again only after it recovered).
    fn shrunk(&mut self, step: usize, range: Option<DisparityRange>) -> Option<String> {
        let range = range.filter(|_| step > 0)?;
        let shrunk = range.predicted < RANGE_SHARE * range.truth;
        if !shrunk || self.warned_range {
            self.warned_range &= shrunk;
            return None;
        }
        self.warned_range = true;
        Some(format!(
            "step {step}: the teacher's held-out disparities reach {:.1} px ({:.0}th \
             percentile), less than {:.0} % of the ground truth's {:.1} px: the teacher is \
             shrinking toward small disparities (docs/training.md, \"A teacher that drifts\")",
            range.predicted,
            100.0 * RANGE_PERCENTILE,
            100.0 * RANGE_SHARE,
            range.truth
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn range(predicted: f32) -> Option<DisparityRange> {
        Some(DisparityRange {
            predicted,
            truth: 12.8,
        })
    }

    #[test]
    fn a_validation_worse_than_the_best_for_the_stretch_is_named_once() {
        // 300 steps: the stretch is 30.
        let mut watch = DriftWatch::new(300);
        assert_eq!(watch.observe(0, 99.8, range(30.0)), Verdict::default());
        let best = watch.observe(150, 46.7, range(12.0));
        assert!(best.best && best.warnings.is_empty(), "{best:?}");
        // Within the margin, then worse but too soon after the best.
        assert!(watch.observe(160, 51.0, range(12.0)).warnings.is_empty());
        let mut soon = DriftWatch::new(300);
        soon.observe(150, 46.7, None);
        assert!(soon.observe(170, 86.5, None).warnings.is_empty());
        let drift = watch.observe(300, 86.5, range(12.0));
        assert!(!drift.best);
        assert_eq!(drift.warnings.len(), 1, "{drift:?}");
        assert!(
            drift.warnings[0].starts_with(
                "step 300: held-out Out-3 ALL is 86.5 %, 39.8 points worse than its best (46.7 % \
                 at step 150) 150 steps later"
            ),
            "{}",
            drift.warnings[0]
        );
        assert!(watch.observe(310, 90.0, None).warnings.is_empty(), "once");
        // A new best re-arms the watch.
        assert!(watch.observe(320, 40.0, None).best);
        assert_eq!(watch.observe(360, 60.0, None).warnings.len(), 1);
        assert_eq!(
            watch.best(),
            Some(Best {
                step: 320,
                out3: 40.0
            })
        );
    }

    #[test]
    fn a_shrunk_range_is_named_and_the_untrained_network_is_never_best() {
        let mut watch = DriftWatch::new(100);
        assert!(!watch.observe(0, 10.0, range(1.0)).best, "step 0");
        let shrunk = watch.observe(50, 60.0, range(5.0));
        assert!(shrunk.best);
        assert_eq!(shrunk.warnings.len(), 1, "{shrunk:?}");
        assert!(
            shrunk.warnings[0].starts_with(
                "step 50: the teacher's held-out disparities reach 5.0 px (95th percentile), less \
                 than 50 % of the ground truth's 12.8 px"
            ),
            "{}",
            shrunk.warnings[0]
        );
        assert!(watch.observe(60, 60.0, range(5.0)).warnings.is_empty());
        assert!(watch.observe(70, 60.0, range(11.0)).warnings.is_empty());
        assert_eq!(watch.observe(80, 60.0, range(4.0)).warnings.len(), 1);
    }

    #[test]
    fn a_resumed_watch_knows_the_best_of_the_log() {
        let lines = [
            json!({"step": 0, "ALL": {"out3": 5.0}}),
            json!({"step": 100, "ALL": {"out3": 50.0}}),
            json!({"step": 200, "ALL": {"out3": 30.0}}),
            json!({"step": 300, "ALL": {"out3": 45.0}}),
        ];
        let watch = DriftWatch::resumed(1000, &lines);
        assert_eq!(
            watch.best(),
            Some(Best {
                step: 200,
                out3: 30.0
            })
        );
    }
}
