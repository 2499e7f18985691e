//! Range checks of settings, the networks' and the trainer's: every
//! check goes through these, so each refusal names the setting, the value
//! and what is allowed in the same words.

use crate::error::NetError;

/// Refuses `value` of setting `name` unless `ok`, saying what is allowed.
pub fn require(
    ok: bool,
    name: &'static str,
    value: impl ToString,
    allowed: impl Into<String>,
) -> Result<(), NetError> {
    if ok {
        Ok(())
    } else {
        Err(NetError::InvalidSetting {
            name,
            value: value.to_string(),
            reason: allowed.into(),
        })
    }
}

/// An integer in `min..=max`: every size and count of a network or a batch
/// has an upper bound too, so that no setting asks for more memory or time
/// than a machine has before anything is allocated.
pub fn integer_in(
    name: &'static str,
    value: usize,
    (min, max): (usize, usize),
) -> Result<(), NetError> {
    require(
        (min..=max).contains(&value),
        name,
        value,
        format!("an integer from {min} to {max}"),
    )
}

/// A number in `[0, 1]`.
pub fn unit(name: &'static str, value: f64) -> Result<(), NetError> {
    require(
        (0.0..=1.0).contains(&value),
        name,
        value,
        "a number in [0, 1]",
    )
}

/// A finite number above 0.
pub fn positive(name: &'static str, value: f64) -> Result<(), NetError> {
    require(
        value.is_finite() && value > 0.0,
        name,
        value,
        "a positive number",
    )
}

/// A finite number of at least 0.
pub fn non_negative(name: &'static str, value: f64) -> Result<(), NetError> {
    require(
        value.is_finite() && value >= 0.0,
        name,
        value,
        "a non-negative number",
    )
}

/// A count of at least 1.
pub fn at_least_one(name: &'static str, value: usize) -> Result<(), NetError> {
    require(value >= 1, name, value, "at least 1")
}

/// Every named value is in its `(min, max)` range ([`integer_in`]).
pub fn integers_in(named: &[(&'static str, usize, (usize, usize))]) -> Result<(), NetError> {
    named
        .iter()
        .try_for_each(|&(name, value, range)| integer_in(name, value, range))
}

/// The sizes RAFT-Stereo and IGEV-Stereo share, each in its range: hidden
/// channels, correlation pyramid (levels, radius) and update iterations
/// (training, test).
pub fn iterative_network(
    hidden_dim: usize,
    (corr_levels, corr_radius): (usize, usize),
    (train_iters, test_iters): (usize, usize),
) -> Result<(), NetError> {
    integers_in(&[
        ("hidden_dim", hidden_dim, CHANNELS),
        ("corr_levels", corr_levels, CORRELATION_LEVELS),
        ("corr_radius", corr_radius, CORRELATION_RADIUS),
        ("train_iters", train_iters, ITERATIONS),
        ("test_iters", test_iters, ITERATIONS),
    ])
}

/// Channels of a network's feature and hidden layers (the official
/// networks use 128 to 256).
pub const CHANNELS: (usize, usize) = (1, 1024);
/// Iterations of an iterative network's update (the official ones use up
/// to 32).
pub const ITERATIONS: (usize, usize) = (1, 256);
/// Levels of a correlation pyramid.
pub const CORRELATION_LEVELS: (usize, usize) = (1, 6);
/// Radius of a correlation lookup.
pub const CORRELATION_RADIUS: (usize, usize) = (0, 16);
/// Largest disparity a network's cost volume covers.
pub const MAX_DISPARITY: usize = 1024;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_name_the_setting_value_and_range() {
        assert!(unit("alpha", 1.0).is_ok());
        let err = unit("alpha", 1.5).unwrap_err().to_string();
        assert_eq!(err, "invalid setting `alpha` = 1.5: a number in [0, 1]");
        assert!(positive("tau", f64::NAN).is_err());
        assert!(positive("tau", 0.0).is_err());
        assert!(non_negative("omega", 0.0).is_ok());
        assert!(non_negative("omega", f64::INFINITY).is_err());
        let err = at_least_one("workers", 0).unwrap_err().to_string();
        assert_eq!(err, "invalid setting `workers` = 0: at least 1");
        let err = integer_in("hidden_dim", 100_000, CHANNELS)
            .unwrap_err()
            .to_string();
        assert_eq!(
            err,
            "invalid setting `hidden_dim` = 100000: an integer from 1 to 1024"
        );
    }
}
