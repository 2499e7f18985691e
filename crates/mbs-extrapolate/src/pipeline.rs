//! The extrapolation of one pair in memory: each view warped outwards by
//! its own disparity, its holes masked (and dilated), then inpainted.

use mbs_core::{FloatImage, MaskImage, RgbImage, Side};
use mbs_infer::inpaint::Inpainter;
use mbs_warp::{Dilation, extrapolate_view};

use crate::{Disparities, ExtrapolateError};

/// The two new views of a pair and what was synthesised in them.
#[derive(Debug, Clone, PartialEq)]
pub struct NewViews {
    /// The new view one baseline left of the left view (camera 1 of 4).
    pub image_1: RgbImage,
    /// The new view one baseline right of the right view (camera 4 of 4).
    pub image_4: RgbImage,
    /// Pixels of `image_1` that were inpainted (255): holes and dilation.
    pub mask_1: MaskImage,
    /// Pixels of `image_4` that were inpainted (255).
    pub mask_4: MaskImage,
    /// Pixels of `image_1` no source pixel landed on (before dilation).
    pub holes_1: MaskImage,
    /// Pixels of `image_4` no source pixel landed on.
    pub holes_4: MaskImage,
}

/// One synthesised view and what was synthesised in it.
#[derive(Debug, Clone, PartialEq)]
pub struct NewView {
    /// The view, inpainted.
    pub image: RgbImage,
    /// Pixels that were inpainted (255): holes and dilation.
    pub mask: MaskImage,
    /// Pixels no source pixel landed on (before dilation).
    pub holes: MaskImage,
}

/// Extrapolates pairs with one mask dilation and one inpainter.
pub struct Extrapolator {
    /// How hole masks grow before inpainting.
    pub dilation: Dilation,
    /// What fills the masked pixels.
    pub inpainter: Box<dyn Inpainter>,
}

impl Extrapolator {
    /// An extrapolator with this dilation and inpainter.
    pub fn new(dilation: Dilation, inpainter: Box<dyn Inpainter>) -> Self {
        Self {
            dilation,
            inpainter,
        }
    }

    /// The new views of the rectified pair (`left`, `right`) whose
    /// disparities are `disparities`. Views of different sizes are an error.
    pub fn extrapolate(
        &self,
        left: &RgbImage,
        right: &RgbImage,
        disparities: &Disparities,
    ) -> Result<NewViews, ExtrapolateError> {
        if left.dimensions() != right.dimensions() {
            return Err(ExtrapolateError::Warp(mbs_warp::WarpError::SizeMismatch {
                what: "the right view",
                expected: left.dimensions(),
                found: right.dimensions(),
            }));
        }
        let first = self.synthesize(left, &disparities.left, Side::Left, "image_1")?;
        let last = self.synthesize(right, &disparities.right, Side::Right, "image_4")?;
        Ok(NewViews {
            image_1: first.image,
            image_4: last.image,
            mask_1: first.mask,
            mask_4: last.mask,
            holes_1: first.holes,
            holes_4: last.holes,
        })
    }

    /// The view one `disparity` away from `view` towards `side` (the
    /// disparity of `view`, in pixels, against the new camera): `view`
    /// forward-warped, its holes masked and dilated, then inpainted. Every
    /// new view of `extrapolate` and of single-image sets comes from here;
    /// `name` names the new view in errors.
    pub fn synthesize(
        &self,
        view: &RgbImage,
        disparity: &FloatImage,
        side: Side,
        name: &str,
    ) -> Result<NewView, ExtrapolateError> {
        let warped = extrapolate_view(view, disparity, side, self.dilation)?;
        if warped.mask.iter().all(|&m| m > 0) {
            return Err(all_masked(name, &warped.holes, disparity, self.dilation));
        }
        let image = self
            .inpainter
            .inpaint(&warped.image, &warped.mask, Some(&warped.disparity))
            .map_err(|source| ExtrapolateError::Inpaint {
                view: name.to_string(),
                source,
            })?;
        Ok(NewView {
            image,
            mask: warped.mask,
            holes: warped.holes,
        })
    }
}

/// Why every pixel of a new view is masked: the warp already left no pixel
/// (disparities about as wide as the view), or the dilation covered the
/// rest.
fn all_masked(
    view: &str,
    holes: &MaskImage,
    disparity: &FloatImage,
    dilation: Dilation,
) -> ExtrapolateError {
    let width = disparity.width();
    let cause = if holes.iter().all(|&h| h > 0) {
        let largest = disparity
            .iter()
            .copied()
            .filter(|d| d.is_finite())
            .fold(0.0f32, f32::max);
        format!(
            "the warp carries every pixel out of the {width} px wide view (disparities up to \
             {largest} px): check the disparities' scale"
        )
    } else {
        format!(
            "the mask dilation {dilation:?} (radius in pixels) covers the whole {width} px wide view"
        )
    };
    ExtrapolateError::AllMasked {
        view: view.to_string(),
        cause,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_infer::inpaint::BackgroundFill;

    #[test]
    fn a_view_with_nothing_left_to_inpaint_from_says_why() {
        let (width, height) = (32, 8);
        let view = RgbImage::from_fn(width, height, |x, _| image::Rgb([(x * 8) as u8, 0, 0]));
        let disparities = |d: f32| Disparities {
            left: FloatImage::from_pixel(width, height, image::Luma([d])),
            right: FloatImage::from_pixel(width, height, image::Luma([d])),
        };
        let extrapolate = |dilation, d| {
            Extrapolator::new(dilation, Box::new(BackgroundFill::default()))
                .extrapolate(&view, &view, &disparities(d))
                .map(drop)
                .map_err(|e| e.to_string())
        };
        assert!(extrapolate(Dilation::None, 2.0).is_ok());
        let err = extrapolate(Dilation::None, 1e30).unwrap_err();
        assert!(
            err.starts_with("image_1: every pixel is masked")
                && err.contains("carries every pixel out of the 32 px wide view"),
            "{err}"
        );
        let err = extrapolate(Dilation::Square(100_000), 2.0).unwrap_err();
        assert!(
            err.contains("the mask dilation Square(100000) (radius in pixels) covers"),
            "{err}"
        );
    }
}
