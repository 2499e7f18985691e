//! [`OnnxInpainter`]: an ONNX inpainting network (LaMa, MI-GAN style) as an
//! [`Inpainter`].

use std::path::Path;

use image::imageops::{self, FilterType};
use mbs_core::{FloatImage, MaskImage, RgbImage};

use super::card::{ColorOrder, ElementType, ModelCard, SizePolicy, Task};
use super::error::{OnnxError, Result};
use super::model::Model;
use super::runtime::{Device, RuntimeOptions};
use super::tensor::{Element, OutputMaps, Padding, Source, input_shape, write_item};
use crate::inpaint::{InpaintError, Inpainter, check_inputs};

/// Context kept around the holes when they do not fit a fixed-size model.
const MARGIN: u32 = 16;

/// An inpainting network run through ONNX Runtime, fed as its [`ModelCard`]
/// says (image plus mask in, image out).
///
/// Dynamic-size models see the whole image, padded to the card's multiple.
/// Fixed-size models (LaMa 512x512) see a window around the holes' bounding
/// box: exactly the model's size when the holes fit (no resampling), else
/// the bounding box plus a margin, widened to the model's aspect ratio and
/// resized. Only masked pixels are taken from the model's output.
pub struct OnnxInpainter {
    model: Model,
    name: String,
}

impl OnnxInpainter {
    /// Opens `model` with an inpainting `card`, checking the model's inputs
    /// and outputs against it.
    pub fn open(model: &Path, card: ModelCard, options: &RuntimeOptions) -> Result<OnnxInpainter> {
        let name = format!("onnx:{}", card.name);
        Ok(OnnxInpainter {
            model: Model::open(model, card, Task::Inpaint, options)?,
            name,
        })
    }

    /// The device the model runs on (the CPU after an allowed fallback).
    pub fn device(&self) -> Device {
        self.model.device()
    }

    /// Inpaints the window `(x, y, width, height)` of `image`.
    fn inpaint_window(
        &self,
        image: &RgbImage,
        mask: &MaskImage,
        (x, y, w, h): (u32, u32, u32, u32),
    ) -> Result<RgbImage> {
        let card = self.model.card();
        let mut crop = imageops::crop_imm(image, x, y, w, h).to_image();
        let mut crop_mask = imageops::crop_imm(mask, x, y, w, h).to_image();
        let size = match card.size {
            SizePolicy::Fixed { width, height } if (width, height) != (w, h) => {
                crop = imageops::resize(&crop, width, height, FilterType::Triangle);
                // Any trace of a hole stays a hole: never feed a hole as known.
                crop_mask = imageops::resize(&crop_mask, width, height, FilterType::Triangle);
                crop_mask
                    .iter_mut()
                    .for_each(|m| *m = if *m > 0 { 255 } else { 0 });
                (width, height)
            }
            _ => (w, h),
        };
        let filled = match card.dtype {
            ElementType::Float32 => self.infer::<f32>(&crop, &crop_mask, size)?,
            ElementType::Uint8 => self.infer::<u8>(&crop, &crop_mask, size)?,
        };
        Ok(if size == (w, h) {
            filled
        } else {
            imageops::resize(&filled, w, h, FilterType::Triangle)
        })
    }

    /// Runs the model on one image of `size` and returns its output image.
    fn infer<T: Element>(
        &self,
        image: &RgbImage,
        mask: &MaskImage,
        size: (u32, u32),
    ) -> Result<RgbImage> {
        let card = self.model.card();
        let (spec, Some(image_name), Some(mask_name)) =
            (card.mask, card.input("image"), card.input("mask"))
        else {
            return Err(self
                .model
                .run_error("the card names no image and mask inputs"));
        };
        let spec = spec.ok_or_else(|| self.model.run_error("the card has no mask values"))?;
        let (fill, pad) = match card.size {
            SizePolicy::Dynamic { fill, .. } => {
                (fill, Padding::for_card(size.0, size.1, &card.size))
            }
            SizePolicy::Fixed { .. } => (Default::default(), Padding::default()),
        };
        let padded = pad.padded(size.0, size.1);
        let plane = padded.0 as usize * padded.1 as usize;
        let shape = |c: i64| input_shape(card.layout, 1, padded, c);
        let mut image_data = vec![T::default(); 3 * plane];
        write_item(
            &mut image_data,
            &[Source::rgb(image, card)],
            size,
            pad,
            fill,
            card.layout,
        );
        let mut mask_data = vec![T::default(); plane];
        write_item(
            &mut mask_data,
            &[Source::mask(mask, spec)],
            size,
            pad,
            fill,
            card.layout,
        );
        let planes = self.model.run::<T, _>(
            vec![
                (image_name, shape(3), image_data),
                (mask_name, shape(1), mask_data),
            ],
            |dims, data| self.colour_planes(dims, data, pad, size),
        )?;
        let scale = card.output.scale;
        Ok(RgbImage::from_fn(size.0, size.1, |x, y| {
            image::Rgb(std::array::from_fn(|c| {
                u8::from_f32(planes[c].get_pixel(x, y).0[0] * scale)
            }))
        }))
    }

    /// The red, green and blue planes of an output tensor of shape `dims`
    /// holding one image of `size` padded by `pad`, padding removed.
    fn colour_planes<T: Element>(
        &self,
        dims: &[i64],
        data: &[T],
        pad: Padding,
        size: (u32, u32),
    ) -> Result<[FloatImage; 3]> {
        let card = self.model.card();
        let (pw, ph) = pad.padded(size.0, size.1);
        let order = match card.color_order {
            ColorOrder::Rgb => [0, 1, 2],
            ColorOrder::Bgr => [2, 1, 0],
        };
        let maps = OutputMaps::locate(dims, 1, (pw, ph))
            .filter(|m| m.channels() == 3)
            .ok_or_else(|| {
                self.model.run_error(format!(
                    "output {:?} has shape {dims:?}; expected one 3-channel {pw}x{ph} image",
                    card.output.name
                ))
            })?;
        Ok(order.map(|c| maps.crop(data, (0, c), pw, pad, size)))
    }

    /// The window the model sees for holes within `bbox` in an image of
    /// `size`.
    fn window(&self, size: (u32, u32), bbox: (u32, u32, u32, u32)) -> (u32, u32, u32, u32) {
        let SizePolicy::Fixed { width, height } = self.model.card().size else {
            return (0, 0, size.0, size.1);
        };
        window_around(size, bbox, (width, height))
    }
}

/// A window of at least `model` size (clipped to the image) around `bbox`,
/// with a margin when the box does not fit, widened towards the model's
/// aspect ratio, as centred on the box as the image allows.
fn window_around(
    (iw, ih): (u32, u32),
    (bx, by, bw, bh): (u32, u32, u32, u32),
    (mw, mh): (u32, u32),
) -> (u32, u32, u32, u32) {
    let need = |b: u32, m: u32| if b <= m { m } else { b + 2 * MARGIN };
    let (mut w, mut h) = (need(bw, mw), need(bh, mh));
    // Widen the shorter side so that resizing keeps the aspect ratio.
    let (mw64, mh64) = (u64::from(mw), u64::from(mh));
    h = h.max(u64::from(w).saturating_mul(mh64).div_ceil(mw64) as u32);
    w = w.max(u64::from(h).saturating_mul(mw64).div_ceil(mh64) as u32);
    let (w, h) = (w.min(iw), h.min(ih));
    let place = |b: u32, bl: u32, l: u32, il: u32| {
        let centre = i64::from(b) + i64::from(bl) / 2;
        (centre - i64::from(l) / 2).clamp(0, i64::from(il - l)) as u32
    };
    (place(bx, bw, w, iw), place(by, bh, h, ih), w, h)
}

/// The bounding box `(x, y, width, height)` of the non-zero pixels.
fn bounding_box(mask: &MaskImage) -> Option<(u32, u32, u32, u32)> {
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (x, y, m) in mask.enumerate_pixels() {
        if m.0[0] != 0 {
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
        }
    }
    (x0 != u32::MAX).then(|| (x0, y0, x1 - x0 + 1, y1 - y0 + 1))
}

impl Inpainter for OnnxInpainter {
    fn name(&self) -> &str {
        &self.name
    }

    fn inpaint(
        &self,
        image: &RgbImage,
        mask: &MaskImage,
        disparity: Option<&FloatImage>,
    ) -> std::result::Result<RgbImage, InpaintError> {
        check_inputs(image, mask, disparity)?;
        let Some(bbox) = bounding_box(mask) else {
            return Ok(image.clone());
        };
        let window = self.window(image.dimensions(), bbox);
        let filled = self
            .inpaint_window(image, mask, window)
            .map_err(|e: OnnxError| InpaintError::Backend(e.to_string()))?;
        let mut out = image.clone();
        let (x0, y0, _, _) = window;
        for (x, y, p) in filled.enumerate_pixels() {
            if mask.get_pixel(x0 + x, y0 + y).0[0] != 0 {
                out.put_pixel(x0 + x, y0 + y, *p);
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_fit_the_model_when_the_holes_do() {
        // A 10x10 hole near the bottom-right corner of a 200x150 image.
        assert_eq!(
            window_around((200, 150), (180, 130, 10, 10), (64, 64)),
            (136, 86, 64, 64)
        );
        // Holes wider than the model: box + margins, model aspect ratio.
        assert_eq!(
            window_around((300, 300), (100, 100, 100, 10), (64, 64)),
            (84, 39, 132, 132)
        );
        // Images smaller than the model: the whole image.
        assert_eq!(
            window_around((40, 30), (5, 5, 3, 3), (64, 64)),
            (0, 0, 40, 30)
        );
    }

    #[test]
    fn bounding_boxes_cover_the_holes() {
        let mut mask = MaskImage::new(8, 6);
        assert_eq!(bounding_box(&mask), None);
        mask.put_pixel(2, 1, image::Luma([255]));
        mask.put_pixel(5, 4, image::Luma([1]));
        assert_eq!(bounding_box(&mask), Some((2, 1, 4, 4)));
    }
}
