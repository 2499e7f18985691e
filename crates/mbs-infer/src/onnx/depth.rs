//! [`OnnxDepth`]: a monocular depth network (FastDepth, Depth Anything,
//! MiDaS) run through ONNX Runtime as its card says: one image in, a map on
//! the image's grid out, with what the map holds (the card's
//! [`DepthKind`]).

use std::path::Path;

use image::imageops::{self, FilterType};
use mbs_core::{FloatImage, RgbImage};

use super::card::{ElementType, ModelCard, SizePolicy, Task};
use super::error::Result;
use super::model::Model;
use super::resize::resize_bilinear;
use super::runtime::{Device, RuntimeOptions};
use super::tensor::{Element, OutputMaps, Padding, Source, input_shape, write_item};
use crate::depth::{DepthEstimator, DepthMap};

/// A monocular depth network run through ONNX Runtime, fed as its
/// [`ModelCard`] says. A fixed-size model sees the image resized to its
/// size (its map is resized back, bilinearly); a dynamic one sees it padded
/// to the card's multiple (its map is cropped back).
pub struct OnnxDepth {
    model: Model,
}

impl OnnxDepth {
    /// Opens `model` with a depth `card`, checking the model's input and
    /// output against it.
    pub fn open(model: &Path, card: ModelCard, options: &RuntimeOptions) -> Result<OnnxDepth> {
        Ok(OnnxDepth {
            model: Model::open(model, card, Task::Depth, options)?,
        })
    }

    /// The device the model runs on (the CPU after an allowed fallback).
    pub fn device(&self) -> Device {
        self.model.device()
    }

    /// The model's card.
    pub fn card(&self) -> &ModelCard {
        self.model.card()
    }

    /// The map of `image`; an error naming the model when the map is not
    /// of the kind its card says (NaN, a metric depth of zero...).
    pub fn predict(&self, image: &RgbImage) -> Result<DepthMap> {
        let card = self.model.card();
        let size = image.dimensions();
        let resized;
        let (input, input_size) = match card.size {
            SizePolicy::Fixed { width, height } if (width, height) != size => {
                resized = imageops::resize(image, width, height, FilterType::Triangle);
                (&resized, (width, height))
            }
            _ => (image, size),
        };
        let pad = Padding::for_card(input_size.0, input_size.1, &card.size);
        let map = match card.dtype {
            ElementType::Float32 => self.infer::<f32>(input, input_size, pad)?,
            ElementType::Uint8 => self.infer::<u8>(input, input_size, pad)?,
        };
        let mut values = match input_size == size {
            true => map,
            false => resize_bilinear(&map, size.0, size.1),
        };
        let kind = card
            .output
            .kind
            .ok_or_else(|| self.model.run_error("the depth card has no output.kind"))?;
        let scale = card.output.scale;
        values.iter_mut().for_each(|v| *v *= scale);
        if let Some(problem) = kind.problem(&values) {
            return Err(self.model.run_error(format!("the card's output {problem}")));
        }
        Ok(DepthMap { values, kind })
    }

    /// Runs the model on `image` (already at the model's size) and returns
    /// its map, cropped back from the padding.
    fn infer<T: Element>(
        &self,
        image: &RgbImage,
        size: (u32, u32),
        pad: Padding,
    ) -> Result<FloatImage> {
        let card = self.model.card();
        let (pw, ph) = pad.padded(size.0, size.1);
        let fill = match card.size {
            SizePolicy::Dynamic { fill, .. } => fill,
            SizePolicy::Fixed { .. } => Default::default(),
        };
        let mut data = vec![T::default(); 3 * pw as usize * ph as usize];
        write_item(
            &mut data,
            &[Source::rgb(image, card)],
            size,
            pad,
            fill,
            card.layout,
        );
        let name = card
            .input("image")
            .ok_or_else(|| self.model.run_error("the card names no image input"))?;
        let inputs = vec![(name, input_shape(card.layout, 1, (pw, ph), 3), data)];
        let read = |dims: &[i64], values: &[T]| {
            let maps = OutputMaps::locate(dims, 1, (pw, ph)).ok_or_else(|| {
                self.model.run_error(format!(
                    "output {:?} has shape {dims:?}; expected a map of {pw}x{ph}",
                    card.output.name
                ))
            })?;
            Ok(maps.crop(values, (0, 0), pw, pad, size))
        };
        self.model.run::<T, _>(inputs, read)
    }
}

impl DepthEstimator for OnnxDepth {
    fn estimate(&self, image: &RgbImage) -> std::result::Result<DepthMap, crate::InferError> {
        self.predict(image).map_err(super::stereo::backend)
    }
}
