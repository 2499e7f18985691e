//! Range checks of settings, the networks' and the trainer's: every
//! check goes through these, so each refusal names the setting, the value
//! and what is allowed in the same words.

use crate::error::NetError;

/// Refuses `value` of setting `name` unless `ok`, saying what is allowed.
pub fn require(
    ok: bool,
    name: &'static str,
    value: impl ToString,
    allowed: &'static str,
) -> Result<(), NetError> {
    if ok {
        Ok(())
    } else {
        Err(NetError::InvalidSetting {
            name,
            value: value.to_string(),
            reason: allowed,
        })
    }
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

/// Every named count is at least 1.
pub fn counts(named: &[(&'static str, usize)]) -> Result<(), NetError> {
    named
        .iter()
        .try_for_each(|&(name, value)| at_least_one(name, value))
}

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
    }
}
