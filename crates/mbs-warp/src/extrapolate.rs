//! One extrapolated view before inpainting: forward warp, hole mask, and the
//! dilated mask of pixels to re-synthesise (conventions §4, steps 2 and 3).

use mbs_core::{FloatImage, MaskImage, RgbImage, Side};

use crate::error::WarpError;
use crate::forward::forward_warp;
use crate::morph::{EdgeSide, Shape, dilate, dilate_one_side};

/// How the hole mask is grown before inpainting, to also re-synthesise the
/// pixels next to holes where an estimated disparity is doubtful.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Dilation {
    /// Only the holes themselves are re-synthesised.
    #[default]
    None,
    /// Dilation by a square of this radius (size `2r + 1`).
    Square(u32),
    /// Dilation by a disc of this radius (OpenCV's elliptical element).
    Ellipse(u32),
    /// Holes at depth edges grow by this many pixels on their background
    /// side only (see [`dilate_one_side`]).
    BackgroundSide(u32),
    /// Holes at depth edges grow by this many pixels on their foreground
    /// side only, where pixels carried by a too-large disparity land.
    ForegroundSide(u32),
}

impl Dilation {
    /// The mask of pixels to re-synthesise for `holes`, given the warped
    /// `disparity` on the same grid.
    pub fn apply(self, holes: &MaskImage, disparity: &FloatImage) -> Result<MaskImage, WarpError> {
        Ok(match self {
            Dilation::None => holes.clone(),
            Dilation::Square(r) => dilate(holes, Shape::Square, r),
            Dilation::Ellipse(r) => dilate(holes, Shape::Ellipse, r),
            Dilation::BackgroundSide(r) => {
                dilate_one_side(holes, disparity, r, EdgeSide::Background)?
            }
            Dilation::ForegroundSide(r) => {
                dilate_one_side(holes, disparity, r, EdgeSide::Foreground)?
            }
        })
    }
}

/// A view warped one baseline further, ready for inpainting.
#[derive(Debug, Clone, PartialEq)]
pub struct WarpedView {
    /// The warped view; holes are black, masked pixels are to be replaced.
    pub image: RgbImage,
    /// 255 where nothing landed.
    pub holes: MaskImage,
    /// 255 where the view must be synthesised: the holes grown by the dilation.
    pub mask: MaskImage,
    /// The warped disparity (`+inf` in holes): the depth guide for inpainting.
    pub disparity: FloatImage,
}

/// Warps `image` by its own `disparity` one baseline further towards `side`
/// (the left view of a pair with [`Side::Left`] to `-B`, the right view with
/// [`Side::Right`] to `+2B`) and builds the mask to inpaint.
pub fn extrapolate_view(
    image: &RgbImage,
    disparity: &FloatImage,
    side: Side,
    dilation: Dilation,
) -> Result<WarpedView, WarpError> {
    let warped = forward_warp(image, disparity, side)?;
    let mask = dilation.apply(&warped.holes, &warped.disparity)?;
    Ok(WarpedView {
        image: warped.image,
        holes: warped.holes,
        mask,
        disparity: warped.disparity,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_shift_masks_the_entering_border_grown_by_the_dilation() {
        let image = RgbImage::from_pixel(12, 5, image::Rgb([9, 9, 9]));
        let disp = FloatImage::from_pixel(12, 5, image::Luma([2.0]));
        let none = extrapolate_view(&image, &disp, Side::Left, Dilation::None).unwrap();
        let square = extrapolate_view(&image, &disp, Side::Left, Dilation::Square(1)).unwrap();
        for y in 0..5 {
            for x in 0..12 {
                assert_eq!(none.mask.get_pixel(x, y).0[0] == 255, x < 2);
                assert_eq!(square.mask.get_pixel(x, y).0[0] == 255, x < 3);
            }
        }
        assert_eq!(square.holes, none.holes);
        // Border holes are no depth edge: background-side dilation keeps them.
        let bg = extrapolate_view(&image, &disp, Side::Left, Dilation::BackgroundSide(4)).unwrap();
        assert_eq!(bg.mask, none.holes);
    }
}
