//! Schedules: one-cycle learning rate, the cosine EMA momentum and the
//! geometry term's ramp.

use std::f64::consts::PI;

use burn::config::Config;

use crate::error::TrainError;
use mbs_nets::ranges;

/// How the one-cycle schedule moves between its end points.
#[derive(Config, Debug, Copy, PartialEq)]
pub enum Anneal {
    /// Straight line (IGEV-Stereo and RAFT-Stereo train with this).
    Linear,
    /// Half cosine (PyTorch's default).
    Cosine,
}

impl Anneal {
    /// The value a fraction `pct` of the way from `start` to `end`.
    fn at(self, start: f64, end: f64, pct: f64) -> f64 {
        match self {
            Anneal::Linear => start + (end - start) * pct,
            Anneal::Cosine => end + (start - end) / 2.0 * ((PI * pct).cos() + 1.0),
        }
    }
}

/// One-cycle learning rate, as PyTorch's `OneCycleLR` without momentum
/// cycling: from `max_lr / div_factor` up to `max_lr` over the first
/// `pct_start` of the steps, then down to `max_lr / div_factor / final_div_factor`
/// at step `total_steps - 1`.
#[derive(Config, Debug, PartialEq)]
pub struct OneCycleConfig {
    /// Peak learning rate (2e-4 pretraining, 5e-5 finetuning in the paper).
    pub max_lr: f64,
    /// Number of optimiser steps.
    pub total_steps: usize,
    /// Share of the steps spent warming up (IGEV-Stereo uses 0.01).
    #[config(default = 0.01)]
    pub pct_start: f64,
    /// `max_lr / initial lr`.
    #[config(default = 25.0)]
    pub div_factor: f64,
    /// `initial lr / final lr`.
    #[config(default = 1e4)]
    pub final_div_factor: f64,
    /// Shape of both phases.
    #[config(default = "Anneal::Linear")]
    pub anneal: Anneal,
}

impl OneCycleConfig {
    /// Checks the ranges and gives the schedule.
    pub fn init(&self) -> Result<OneCycle, TrainError> {
        ranges::positive("max_lr", self.max_lr)?;
        ranges::require(
            self.total_steps >= 2,
            "total_steps",
            self.total_steps,
            "at least 2",
        )?;
        ranges::require(
            self.pct_start > 0.0 && self.pct_start < 1.0,
            "pct_start",
            self.pct_start,
            "a number in (0, 1)",
        )?;
        ranges::positive("div_factor", self.div_factor)?;
        ranges::positive("final_div_factor", self.final_div_factor)?;
        let initial = self.max_lr / self.div_factor;
        Ok(OneCycle {
            initial,
            max: self.max_lr,
            min: initial / self.final_div_factor,
            warmup_end: self.pct_start * self.total_steps as f64 - 1.0,
            last: (self.total_steps - 1) as f64,
            anneal: self.anneal,
        })
    }
}

/// A checked one-cycle schedule; see [`OneCycleConfig`].
#[derive(Debug, Clone, PartialEq)]
pub struct OneCycle {
    initial: f64,
    max: f64,
    min: f64,
    warmup_end: f64,
    last: f64,
    anneal: Anneal,
}

impl OneCycle {
    /// Learning rate at optimiser step `step` (0-based; held at the final
    /// value past the end).
    pub fn lr(&self, step: usize) -> f64 {
        let step = (step as f64).min(self.last);
        if step <= self.warmup_end {
            let pct = if self.warmup_end > 0.0 {
                step / self.warmup_end
            } else {
                1.0
            };
            self.anneal.at(self.initial, self.max, pct)
        } else {
            let start = self.warmup_end.max(0.0);
            let pct = (step - start) / (self.last - start);
            self.anneal.at(self.max, self.min, pct)
        }
    }
}

/// EMA momentum on a cosine from `base` at step 0 to 1 at `total_steps`
/// (BYOL): `m = 1 - (1 - base) (cos(pi k / K) + 1) / 2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CosineMomentum {
    /// Momentum at step 0 (0.996 in BYOL).
    pub base: f64,
    /// Step at which the momentum reaches 1.
    pub total_steps: usize,
}

impl CosineMomentum {
    /// Momentum at step `step` (1 from `total_steps` on).
    pub fn at(&self, step: usize) -> f64 {
        if self.total_steps == 0 {
            return 1.0;
        }
        let progress = step.min(self.total_steps) as f64 / self.total_steps as f64;
        1.0 - (1.0 - self.base) * ((PI * progress).cos() + 1.0) / 2.0
    }
}

/// The geometry term's weight over a run: 0 before its start, then rising
/// linearly from 0 over its warm-up, then 1. A schedule like the learning
/// rate's: the trainer passes its value to each step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GeometryRamp {
    /// Steps before the term is on.
    start_steps: usize,
    /// Steps of the warm-up after that.
    warmup_steps: usize,
}

impl GeometryRamp {
    /// The ramp of a run of `total_steps` that switches the term on after
    /// the share `start` of its steps and warms it up over the share
    /// `warmup` after that (`None`: 0). Rounded at the start and at the end
    /// of the warm-up, so that the term reaches its full weight within the
    /// run.
    pub fn new(total_steps: usize, start: Option<f64>, warmup: Option<f64>) -> Self {
        let step_at = |share: f64| (share * total_steps as f64).round() as usize;
        let start = start.unwrap_or(0.0);
        let warmup_end = step_at(start + warmup.unwrap_or(0.0));
        Self {
            start_steps: step_at(start),
            warmup_steps: warmup_end - step_at(start),
        }
    }

    /// The weight at step `step` (0-based).
    pub fn at(&self, step: usize) -> f64 {
        let Some(since) = step.checked_sub(self.start_steps) else {
            return 0.0;
        };
        match self.warmup_steps {
            0 => 1.0,
            steps => (since as f64 / steps as f64).min(1.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1.0)
    }

    #[test]
    fn one_cycle_linear_start_peak_middle_end() {
        let schedule = OneCycleConfig::new(2e-4, 1000).init().expect("valid");
        // Warm-up ends at step 0.01 * 1000 - 1 = 9.
        assert!(close(schedule.lr(0), 8e-6));
        assert!(close(schedule.lr(9), 2e-4));
        // Half-way through the decay from step 9 to step 999 (step 504).
        let min = 8e-6 / 1e4;
        assert!(close(schedule.lr(504), (2e-4 + min) / 2.0));
        assert!(close(schedule.lr(999), min));
        assert!(close(schedule.lr(5000), min));
    }

    #[test]
    fn one_cycle_cosine_matches_pytorch_formula() {
        let schedule = OneCycleConfig::new(1.0, 101)
            .with_pct_start(0.3)
            .with_div_factor(10.0)
            .with_final_div_factor(100.0)
            .with_anneal(Anneal::Cosine)
            .init()
            .expect("valid");
        // Warm-up end 0.3 * 101 - 1 = 29.3; at step 29 pct = 29/29.3.
        let pct = 29.0 / 29.3;
        let want = 1.0 + (0.1 - 1.0) / 2.0 * ((PI * pct).cos() + 1.0);
        assert!(close(schedule.lr(29), want));
        assert!(close(schedule.lr(0), 0.1));
        assert!(close(schedule.lr(100), 0.001));
        assert!(OneCycleConfig::new(1.0, 1).init().is_err());
    }

    #[test]
    fn cosine_momentum_start_middle_end() {
        let schedule = CosineMomentum {
            base: 0.996,
            total_steps: 100,
        };
        assert!(close(schedule.at(0), 0.996));
        assert!(close(schedule.at(50), 0.998));
        assert!(close(schedule.at(100), 1.0));
        assert!(close(schedule.at(250), 1.0));
        // A quarter of the way: 1 - 0.004 (cos(pi/4) + 1) / 2.
        assert!(close(
            schedule.at(25),
            1.0 - 0.004 * (0.5f64.sqrt() + 1.0) / 2.0
        ));
    }
}
