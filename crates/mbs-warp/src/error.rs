//! The error type of warping: inputs that do not fit together.

/// Why a warp could not run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WarpError {
    /// Two inputs that must share one pixel grid have different sizes.
    #[error("{what} is {found:?} (width, height) but the image is {expected:?}")]
    SizeMismatch {
        /// Which input has the wrong size.
        what: &'static str,
        /// The image size, (width, height).
        expected: (u32, u32),
        /// The size found, (width, height).
        found: (u32, u32),
    },
}

/// Checks that `found` has the `expected` size, naming `what` otherwise.
pub(crate) fn check_size(
    what: &'static str,
    expected: (u32, u32),
    found: (u32, u32),
) -> Result<(), WarpError> {
    if expected == found {
        Ok(())
    } else {
        Err(WarpError::SizeMismatch {
            what,
            expected,
            found,
        })
    }
}
