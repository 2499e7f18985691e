//! Integer arguments checked with their names: pyo3 converts a Python
//! `int` to a Rust integer with an `OverflowError` that names nothing
//! (`-1` for a `u32`), and puts an argument's name only in a note of other
//! errors. An [`Integer`] takes any integer (`int`, NumPy's integers,
//! anything with `__index__`; not `bool`) whatever its value, and
//! [`Integer::within`] refuses it with a `TypeError` or `ValueError` that
//! begins with the argument's name.

use std::ops::RangeInclusive;

use pyo3::exceptions::{PyOverflowError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::PyBool;

use crate::{describe, value_error};

/// An integer argument as Python passed it, not yet checked.
pub struct Integer(Result<i128, NotAnInteger>);

/// Why an argument is not an integer mbs can take.
enum NotAnInteger {
    /// Something else (a float, a string, a bool), described.
    Other(String),
    /// An integer beyond 128 bits, as Python prints it.
    Huge(String),
}

impl Integer {
    /// An integer given in Rust, such as an argument's default.
    pub const fn of(value: i128) -> Self {
        Integer(Ok(value))
    }

    /// The value as a `T`, if it is an integer in `range`: else a
    /// `TypeError` or `ValueError` naming argument `name` and the range.
    pub fn within<T: TryFrom<i128>>(self, name: &str, range: RangeInclusive<i128>) -> PyResult<T> {
        let (low, high) = range.into_inner();
        let out_of_range = |value: &dyn std::fmt::Display| {
            value_error(
                name,
                format!("{value} is out of range: expected an integer from {low} to {high}"),
            )
        };
        let value = match self.0 {
            Ok(value) => value,
            Err(NotAnInteger::Huge(text)) => return Err(out_of_range(&text)),
            Err(NotAnInteger::Other(what)) => {
                return Err(PyTypeError::new_err(format!(
                    "{name}: expected an integer, got {what}"
                )));
            }
        };
        if !(low..=high).contains(&value) {
            return Err(out_of_range(&value));
        }
        T::try_from(value).map_err(|_| out_of_range(&value))
    }
}

impl<'a, 'py> FromPyObject<'a, 'py> for Integer {
    type Error = std::convert::Infallible;

    /// Never fails, so that [`Integer::within`] can name the argument.
    fn extract(object: Borrowed<'a, 'py, PyAny>) -> Result<Self, Self::Error> {
        if object.is_instance_of::<PyBool>() {
            return Ok(Integer(Err(NotAnInteger::Other("a bool".into()))));
        }
        Ok(Integer(match object.extract::<i128>() {
            Ok(value) => Ok(value),
            Err(error) if error.is_instance_of::<PyOverflowError>(object.py()) => {
                let text = object
                    .str()
                    .map_or_else(|_| "an integer".into(), |s| s.to_string());
                Err(NotAnInteger::Huge(text))
            }
            Err(_) => Err(NotAnInteger::Other(describe(&object))),
        }))
    }
}
