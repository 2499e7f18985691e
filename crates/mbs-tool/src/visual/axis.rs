//! Plot axes: the range an axis shows and where its labelled ticks go —
//! "nice" steps of 1, 2 or 5 times a power of ten on linear axes, decades
//! on logarithmic ones.

use anyhow::bail;

/// About this many ticks on a linear axis, unless asked otherwise.
pub(super) const TARGET_TICKS: f64 = 6.0;
/// Most decade ticks on a log axis before every n-th is skipped.
const MAX_DECADE_TICKS: i64 = 8;

/// A labelled tick.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Tick {
    /// Where it is, in data units.
    pub value: f64,
    /// What it says.
    pub label: String,
}

/// One axis of a plot: the shown range and its ticks.
#[derive(Debug, Clone)]
pub(super) struct Axis {
    /// Lower end, in axis units (log10 of data units on a log axis).
    lo: f64,
    /// Upper end, in axis units.
    hi: f64,
    /// Whether axis units are log10 of data units.
    log: bool,
    /// Labelled ticks inside the range, in increasing order.
    pub ticks: Vec<Tick>,
}

impl Axis {
    /// A linear axis over `[min, max]` (finite, `min <= max`), widened by
    /// `pad` times the range at each end, with about `target_ticks` ticks
    /// (at least 1). A single value gets a range around it (10 % of the
    /// value either side, or 1 around 0).
    pub fn linear(min: f64, max: f64, pad: f64, target_ticks: f64) -> anyhow::Result<Self> {
        let (lo, hi) = if is_degenerate(min, max) {
            let mid = 0.5 * (min + max);
            let half = if mid == 0.0 { 1.0 } else { 0.1 * mid.abs() };
            (mid - half, mid + half)
        } else {
            (min, max)
        };
        let span = hi - lo;
        let (lo, hi) = (lo - pad * span, hi + pad * span);
        if !(lo.is_finite() && hi.is_finite()) {
            bail!("values up to {max:e} are too large to plot");
        }
        Ok(Self {
            lo,
            hi,
            log: false,
            ticks: linear_ticks(lo, hi, target_ticks.max(1.0)),
        })
    }

    /// A log10 axis over `[min, max]` (finite, `0 < min <= max`), widened by
    /// `pad` times the range (in decades) at each end. A single value gets
    /// a decade around it.
    pub fn log10(min: f64, max: f64, pad: f64) -> Self {
        let (lo, hi) = (min.log10(), max.log10());
        // Log units are absolute: a millionth of a decade is nothing to see.
        let (lo, hi) = if hi - lo <= 1e-6 {
            (lo - 0.5, hi + 0.5)
        } else {
            (lo, hi)
        };
        let span = hi - lo;
        let (lo, hi) = (lo - pad * span, hi + pad * span);
        Self {
            lo,
            hi,
            log: true,
            ticks: log_ticks(lo, hi),
        }
    }

    /// Where `value` (data units) lies along the axis: 0 at the low end,
    /// 1 at the high end.
    pub fn fraction(&self, value: f64) -> f64 {
        let v = if self.log { value.log10() } else { value };
        (v - self.lo) / (self.hi - self.lo)
    }
}

/// Whether `[lo, hi]` is too narrow to plot: below a relative width of
/// 1e-9 the tick labels would need more digits than a plot can show (and
/// tick indices could overflow).
fn is_degenerate(lo: f64, hi: f64) -> bool {
    hi - lo <= 1e-9 * lo.abs().max(hi.abs())
}

/// About `target` ticks at the multiples of a nice step inside `[lo, hi]`
/// (`lo < hi`).
fn linear_ticks(lo: f64, hi: f64, target: f64) -> Vec<Tick> {
    let raw = (hi - lo) / target;
    let mut exp = raw.log10().floor() as i32;
    let f = raw / 10f64.powi(exp);
    let mantissa = match f {
        f if f < 1.5 => 1,
        f if f < 3.5 => 2,
        f if f < 7.5 => 5,
        _ => {
            exp += 1;
            1
        }
    };
    let step = mantissa as f64 * 10f64.powi(exp);
    // A little slack so that an end that is a multiple of the step keeps
    // its tick despite rounding.
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last)
        .map(|i| Tick {
            value: i as f64 * step,
            label: decimal(i * mantissa, exp),
        })
        .collect()
}

/// Ticks of a log axis over `[lo, hi]` (log10 units, `lo < hi`): decades
/// (every n-th when there are many); within less than two decades also
/// 2 and 5 times them, or every digit; within less than a digit, linear
/// ticks.
fn log_ticks(lo: f64, hi: f64) -> Vec<Tick> {
    let first = (lo - 1e-9).ceil() as i64;
    let last = (hi + 1e-9).floor() as i64;
    let decades = last - first + 1;
    if decades >= 2 {
        // Decade ticks on multiples of the stride, so 1 stays labelled.
        let stride = (decades + MAX_DECADE_TICKS - 1) / MAX_DECADE_TICKS;
        return (first..=last)
            .filter(|e| e.rem_euclid(stride) == 0)
            .map(|e| decade_tick(1, e))
            .collect();
    }
    for mantissas in [&[1, 2, 5][..], &[1, 2, 3, 4, 5, 6, 7, 8, 9][..]] {
        let ticks: Vec<Tick> = (first - 1..=last)
            .flat_map(|e| mantissas.iter().map(move |&m| decade_tick(m, e)))
            .filter(|t| {
                let v = t.value.log10();
                v >= lo - 1e-9 && v <= hi + 1e-9
            })
            .collect();
        if ticks.len() >= 3 {
            return ticks;
        }
    }
    let ticks = linear_ticks(10f64.powf(lo), 10f64.powf(hi), TARGET_TICKS);
    // Linear ticks may start at 0, which has no place on a log axis.
    ticks.into_iter().filter(|t| t.value > 0.0).collect()
}

/// The tick at `m * 10^e`.
fn decade_tick(m: i64, e: i64) -> Tick {
    // Exponents of finite f64 values fit in i32 by far.
    let e = e as i32;
    Tick {
        value: m as f64 * 10f64.powi(e),
        label: decimal(m, e),
    }
}

/// `n * 10^exp` written exactly, without floating-point noise: plain
/// (`0.25`, `1500`) when that is at most 6 characters, else in scientific
/// notation (`2.5e-5`, `1e6`).
fn decimal(n: i64, exp: i32) -> String {
    if n == 0 {
        return "0".to_string();
    }
    let sign = if n < 0 { "-" } else { "" };
    let mut digits = n.unsigned_abs().to_string();
    let mut exp = exp;
    while digits.len() > 1 && digits.ends_with('0') {
        digits.pop();
        exp += 1;
    }
    let plain = if exp >= 0 {
        format!("{digits}{}", "0".repeat(exp as usize))
    } else {
        let frac = (-exp) as usize;
        let padded = format!("{digits:0>width$}", width = frac + 1);
        let (int, frac) = padded.split_at(padded.len() - frac);
        format!("{int}.{frac}")
    };
    if plain.len() <= 6 {
        return format!("{sign}{plain}");
    }
    let sci_exp = exp + digits.len() as i32 - 1;
    let (lead, rest) = digits.split_at(1);
    if rest.is_empty() {
        format!("{sign}{lead}e{sci_exp}")
    } else {
        format!("{sign}{lead}.{rest}e{sci_exp}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(ticks: &[Tick]) -> Vec<&str> {
        ticks.iter().map(|t| t.label.as_str()).collect()
    }

    #[test]
    fn decimals_are_exact_and_short() {
        assert_eq!(decimal(0, -3), "0");
        assert_eq!(decimal(25, -2), "0.25");
        assert_eq!(decimal(-5, -1), "-0.5");
        assert_eq!(decimal(15, 2), "1500");
        assert_eq!(decimal(30, -1), "3");
        assert_eq!(decimal(25, -6), "2.5e-5");
        assert_eq!(decimal(1, 6), "1e6");
        assert_eq!(decimal(200, 3), "200000");
    }

    #[test]
    fn linear_ticks_are_nice_multiples() {
        let axis = Axis::linear(0.0, 1000.0, 0.0, TARGET_TICKS).unwrap();
        assert_eq!(
            labels(&axis.ticks),
            ["0", "200", "400", "600", "800", "1000"]
        );
        let axis = Axis::linear(0.12, 0.47, 0.0, TARGET_TICKS).unwrap();
        assert_eq!(
            labels(&axis.ticks),
            ["0.15", "0.2", "0.25", "0.3", "0.35", "0.4", "0.45"]
        );
        assert_eq!(axis.fraction(0.12), 0.0);
        assert!((axis.fraction(0.47) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_single_value_gets_a_range() {
        let axis = Axis::linear(5.0, 5.0, 0.0, TARGET_TICKS).unwrap();
        assert!(axis.fraction(5.0) > 0.0 && axis.fraction(5.0) < 1.0);
        // Fewer ticks on request.
        let axis = Axis::linear(0.0, 1000.0, 0.0, 2.0).unwrap();
        assert_eq!(labels(&axis.ticks), ["0", "500", "1000"]);
        assert!(axis.ticks.len() >= 2);
        let axis = Axis::linear(0.0, 0.0, 0.05, TARGET_TICKS).unwrap();
        assert!(labels(&axis.ticks).contains(&"0"));
        assert!(Axis::linear(-f64::MAX, f64::MAX, 0.1, TARGET_TICKS).is_err());
    }

    #[test]
    fn log_axes_label_decades() {
        let axis = Axis::log10(1e-4, 2.0, 0.0);
        assert_eq!(labels(&axis.ticks), ["0.0001", "0.001", "0.01", "0.1", "1"]);
        assert!((axis.fraction(1e-4)).abs() < 1e-12);
        // Many decades: every other one, keeping 1.
        let axis = Axis::log10(1e-12, 1e3, 0.0);
        assert_eq!(axis.ticks[0].label, "1e-12");
        assert!(axis.ticks.len() <= MAX_DECADE_TICKS as usize);
        assert!(labels(&axis.ticks).contains(&"1"));
    }

    #[test]
    fn narrow_log_axes_get_intermediate_ticks() {
        let axis = Axis::log10(0.05, 0.9, 0.0);
        assert_eq!(labels(&axis.ticks), ["0.05", "0.1", "0.2", "0.5"]);
        let axis = Axis::log10(0.15, 0.9, 0.0);
        let digits = ["0.2", "0.3", "0.4", "0.5", "0.6", "0.7", "0.8", "0.9"];
        assert_eq!(labels(&axis.ticks), digits);
        let axis = Axis::log10(0.31, 0.34, 0.0);
        assert!(axis.ticks.len() >= 2, "{:?}", axis.ticks);
        assert!(
            axis.ticks
                .iter()
                .all(|t| t.value >= 0.31 && t.value <= 0.34)
        );
        // A constant gets a decade around it.
        let axis = Axis::log10(1.0, 1.0, 0.0);
        assert!((axis.fraction(1.0) - 0.5).abs() < 1e-12);
        assert_eq!(labels(&axis.ticks), ["0.5", "1", "2"]);
    }
}
