//! Inpainting: replace the masked pixels of a view with plausible content.
//!
//! [`Inpainter`] is the common interface (an ONNX model such as LaMa or MI-GAN
//! implements it the same way as the built-ins). Built-ins need no model:
//! - [`BackgroundFill`] (the default for extrapolated views): holes after a
//!   forward warp are disocclusions whose true content is the farther
//!   surface, so each hole run is filled from its background side, chosen by
//!   the warped disparity, then smoothed across rows.
//! - [`IsotropicFill`]: fills from the whole rim inwards, like OpenCV's Telea;
//!   a reference and a fallback where no disparity is known.

mod background;
mod border_strip;
mod isotropic;

pub use background::BackgroundFill;
pub use isotropic::IsotropicFill;

use mbs_core::{FloatImage, MaskImage, RgbImage};

/// Why an inpainter could not run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum InpaintError {
    /// The mask or the disparity guide is not on the image's grid.
    #[error("{what} is {found:?} (width, height) but the image is {expected:?}")]
    SizeMismatch {
        /// Which input has the wrong size.
        what: &'static str,
        /// The image size, (width, height).
        expected: (u32, u32),
        /// The size found, (width, height).
        found: (u32, u32),
    },
    /// Every pixel is masked: there is nothing to fill from.
    #[error("the mask covers the whole {0}x{1} image: no pixel to fill from")]
    NothingKnown(u32, u32),
    /// A model backend (ONNX Runtime) failed; the message names the model.
    #[error("{0}")]
    Backend(String),
}

/// Replaces the masked pixels of an image.
pub trait Inpainter: Send + Sync {
    /// A short name for logs and manifests (e.g. `background-fill`).
    fn name(&self) -> &str;

    /// Returns `image` with the pixels where `mask` is non-zero (255 = fill)
    /// replaced; other pixels are kept unchanged. `disparity` is an optional
    /// depth guide on the same grid (larger = nearer, `+inf` = unknown), such
    /// as the warped disparity of an extrapolated view; inpainters that do not
    /// use it ignore it.
    fn inpaint(
        &self,
        image: &RgbImage,
        mask: &MaskImage,
        disparity: Option<&FloatImage>,
    ) -> Result<RgbImage, InpaintError>;
}

/// Checks that `mask` and `disparity` are on `image`'s grid.
pub(crate) fn check_inputs(
    image: &RgbImage,
    mask: &MaskImage,
    disparity: Option<&FloatImage>,
) -> Result<(), InpaintError> {
    let expected = image.dimensions();
    let sizes = [
        ("mask", Some(mask.dimensions())),
        ("disparity", disparity.map(|d| d.dimensions())),
    ];
    for (what, found) in sizes {
        if let Some(found) = found.filter(|f| *f != expected) {
            return Err(InpaintError::SizeMismatch {
                what,
                expected,
                found,
            });
        }
    }
    Ok(())
}

/// An RGB image as floats plus the per-pixel "known" flags: the working
/// state of the built-in fills.
struct Canvas {
    width: usize,
    height: usize,
    rgb: Vec<[f32; 3]>,
    known: Vec<bool>,
}

impl Canvas {
    fn new(image: &RgbImage, mask: &MaskImage) -> Canvas {
        Canvas {
            width: image.width() as usize,
            height: image.height() as usize,
            rgb: image.pixels().map(|p| p.0.map(f32::from)).collect(),
            known: mask.as_raw().iter().map(|m| *m == 0).collect(),
        }
    }

    fn into_image(self) -> RgbImage {
        let raw = self
            .rgb
            .iter()
            .flat_map(|p| p.map(|v| (v + 0.5) as u8)) // rounds; `as` saturates
            .collect();
        RgbImage::from_raw(self.width as u32, self.height as u32, raw)
            .expect("the buffer has width * height RGB pixels by construction")
    }
}
