//! How much supervision each step had, so that a collapse is seen while it
//! happens: the shares of pixels in the student's and teacher's validity
//! masks, the range of the student's disparities and the share of its warps
//! that leave the target image. When the masks stay nearly empty for a
//! while, training has stopped learning (the photometric and geometry terms
//! supervise nothing) and [`CollapseWatch`] says so, naming the cause.

use burn::tensor::Tensor;
use mbs_core::Side;
use mbs_nets::host::read_all;

use crate::error::TrainError;
use crate::losses::warp::outside_share;

/// What one step's masks and student disparities looked like.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Supervision {
    /// Share of pixels in the student's validity mask `M_s` (`None` when
    /// neither the photometric nor the geometry term is on).
    pub student_mask: Option<f32>,
    /// Share of pixels in the teacher's validity mask `M_t` (`None` when
    /// the geometry term is off).
    pub teacher_mask: Option<f32>,
    /// Smallest student disparity (px).
    pub disparity_min: f32,
    /// Mean student disparity (px).
    pub disparity_mean: f32,
    /// Largest student disparity (px).
    pub disparity_max: f32,
    /// Share of pixels whose warp samples outside the student's target.
    pub outside: f32,
}

/// The statistics of a step as one tensor, read back in one transfer by
/// [`Supervision::read`]: mask shares (-1 when absent), disparity min,
/// mean and max, and the outside share.
pub fn measure(
    student_disparity: Tensor<4>,
    sides: &[Side],
    student_mask: Option<Tensor<4>>,
    teacher_mask: Option<Tensor<4>>,
) -> Tensor<1> {
    let disparity = student_disparity.detach();
    let device = disparity.device();
    let share = |mask: Option<Tensor<4>>| {
        mask.map_or_else(|| Tensor::<1>::full([1], -1.0, &device), |m| m.mean())
    };
    Tensor::cat(
        vec![
            share(student_mask),
            share(teacher_mask),
            disparity.clone().min().reshape([1]),
            disparity.clone().mean(),
            disparity.clone().max().reshape([1]),
            outside_share(disparity, sides),
        ],
        0,
    )
}

impl Supervision {
    /// Reads back what [`measure`] computed.
    pub fn read(measured: Tensor<1>) -> Result<Self, TrainError> {
        let v = read_all(measured, "the supervision statistics")?;
        let share = |x: f32| (x >= 0.0).then_some(x);
        Ok(Self {
            student_mask: share(v[0]),
            teacher_mask: share(v[1]),
            disparity_min: v[2],
            disparity_mean: v[3],
            disparity_max: v[4],
            outside: v[5],
        })
    }

    /// The weighted mean of several shares of a step (data parallel), the
    /// extremes over all of them.
    pub fn combine(shares: &[(Supervision, f64)]) -> Self {
        let mean = |value: fn(&Supervision) -> Option<f32>| {
            shares
                .iter()
                .map(|(s, w)| value(s).map(|v| v * *w as f32))
                .sum::<Option<f32>>()
        };
        let extreme = |value: fn(&Supervision) -> f32, pick: fn(f32, f32) -> f32| {
            shares
                .iter()
                .map(|(s, _)| value(s))
                .reduce(pick)
                .unwrap_or(0.0)
        };
        Self {
            student_mask: mean(|s| s.student_mask),
            teacher_mask: mean(|s| s.teacher_mask),
            disparity_min: extreme(|s| s.disparity_min, f32::min),
            disparity_mean: mean(|s| Some(s.disparity_mean)).unwrap_or(0.0),
            disparity_max: extreme(|s| s.disparity_max, f32::max),
            outside: mean(|s| Some(s.outside)).unwrap_or(0.0),
        }
    }

    /// Whether the masks that feed the loss are nearly empty (below
    /// `threshold`): no mask at all counts as full.
    fn starved(&self, threshold: f32) -> bool {
        let student = self.student_mask.is_some_and(|m| m < threshold);
        let teacher = self.teacher_mask.is_none_or(|m| m < threshold);
        student && teacher
    }

    /// Why the masks are empty, as far as the statistics tell.
    fn cause(&self) -> String {
        let range = format!(
            "disparities {:.1} to {:.1} px",
            self.disparity_min, self.disparity_max
        );
        if self.disparity_mean < 0.0 {
            format!(
                "the student predicts negative disparities ({range}): its warps read the wrong \
                 side of the target, which matches worse than no warp at all"
            )
        } else if self.outside > 0.5 {
            format!(
                "{:.0}% of the student's warps leave the image ({range}): the network has \
                 collapsed to disparities no pair can have",
                100.0 * self.outside
            )
        } else if self.disparity_max - self.disparity_min < 0.5 {
            format!("the student predicts one flat value ({range})")
        } else {
            format!(
                "almost no warped pixel passes the mask tests, photometric error below tau and \
                 below the unwarped target's ({range}, {:.0}% of the warps inside the image)",
                100.0 * (1.0 - self.outside)
            )
        }
    }
}

/// Share of pixels below which a validity mask counts as nearly empty.
pub const STARVED_MASK: f32 = 0.02;
/// Steps in a row with nearly empty masks before a warning.
pub const STARVED_STEPS: usize = 10;

/// Watches the steps of a run and warns once supervision has nearly
/// vanished for [`STARVED_STEPS`] steps in a row; it warns again only after
/// supervision came back.
#[derive(Debug, Clone, Default)]
pub struct CollapseWatch {
    starved_for: usize,
    warned: bool,
}

impl CollapseWatch {
    /// Takes one step's statistics; returns the warning when it is due.
    pub fn observe(&mut self, step: usize, supervision: &Supervision) -> Option<String> {
        if !supervision.starved(STARVED_MASK) {
            self.starved_for = 0;
            self.warned = false;
            return None;
        }
        self.starved_for += 1;
        if self.warned || self.starved_for < STARVED_STEPS {
            return None;
        }
        self.warned = true;
        let share = |m: Option<f32>| m.map_or("-".to_string(), |m| format!("{:.1}%", 100.0 * m));
        Some(format!(
            "step {}: supervision has nearly vanished for {} steps (student mask {}, teacher \
             mask {}): {}",
            step + 1,
            self.starved_for,
            share(supervision.student_mask),
            share(supervision.teacher_mask),
            supervision.cause()
        ))
    }
}

/// Percentage points by which held-out Out-3 ALL may rise above the
/// untrained network's before [`worse_than_untrained`] warns.
pub const WORSE_BY_POINTS: f64 = 10.0;

/// A warning when validation at `step` scores the teacher's held-out Out-3
/// ALL (`out3`, %) more than [`WORSE_BY_POINTS`] above the untrained
/// network's (`untrained`): training is making it worse, the mark of a
/// collapse that the masks need not show (some keep 2-8 % of their pixels).
pub fn worse_than_untrained(step: usize, untrained: f64, out3: f64) -> Option<String> {
    (out3 > untrained + WORSE_BY_POINTS).then(|| {
        format!(
            "step {step}: held-out Out-3 ALL is {out3:.1} %, worse than the untrained \
             network's {untrained:.1} %: training is collapsing (docs/training.md, \"S3 from random \
             weights\"; lower --lr, or keep the geometry term off longer)"
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;
    use mbs_nets::test_util::tensor4;

    #[test]
    fn a_teacher_worse_than_untrained_is_warned_about() {
        assert_eq!(worse_than_untrained(120, 64.7, 42.5), None);
        assert_eq!(worse_than_untrained(120, 64.7, 74.7), None);
        let warning = worse_than_untrained(120, 64.7, 96.2).expect("a warning");
        assert!(
            warning.starts_with(
                "step 120: held-out Out-3 ALL is 96.2 %, worse than the untrained network's 64.7 %"
            ),
            "{warning}"
        );
    }

    #[test]
    fn statistics_are_measured_and_read_back() {
        let device = Device::flex();
        // W = 4, target on the right: columns x - d = 0 - 1, 1 - 0, 2 - 1, 3 - 5.
        let d = tensor4(&[1.0, 0.0, 1.0, 5.0], [1, 1, 1, 4], &device);
        let mask = tensor4(&[1.0, 0.0, 0.0, 0.0], [1, 1, 1, 4], &device);
        let s = Supervision::read(measure(d, &[Side::Right], Some(mask), None)).unwrap();
        assert_eq!(s.student_mask, Some(0.25));
        assert_eq!(s.teacher_mask, None);
        assert_eq!((s.disparity_min, s.disparity_max), (0.0, 5.0));
        assert!((s.disparity_mean - 1.75).abs() < 1e-6);
        // Columns -1 and -2 are outside.
        assert_eq!(s.outside, 0.5);
    }

    #[test]
    fn the_watch_warns_once_after_enough_starved_steps_naming_the_cause() {
        let starved = Supervision {
            student_mask: Some(0.001),
            teacher_mask: Some(0.0),
            disparity_min: -244.0,
            disparity_max: -15.0,
            outside: 0.97,
            ..Default::default()
        };
        let fed = Supervision {
            student_mask: Some(0.4),
            ..starved
        };
        let mut watch = CollapseWatch::default();
        let warnings: Vec<String> = (0..3 * STARVED_STEPS)
            .filter_map(|step| watch.observe(step, &starved))
            .collect();
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains("97% of the student's warps leave the image"),
            "{}",
            warnings[0]
        );
        assert!(
            warnings[0].starts_with(&format!("step {STARVED_STEPS}:")),
            "{}",
            warnings[0]
        );
        // Supervision that comes back re-arms the watch.
        assert_eq!(watch.observe(0, &fed), None);
        let again = (0..STARVED_STEPS)
            .filter_map(|s| watch.observe(s, &starved))
            .count();
        assert_eq!(again, 1);
    }
}
