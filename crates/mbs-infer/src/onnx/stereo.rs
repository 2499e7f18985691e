//! [`OnnxStereo`]: an ONNX stereo network as a [`StereoMatcher`].

use std::path::Path;

use image::imageops::{self, FilterType};
use mbs_core::{FloatImage, MaskImage, RgbImage};
use rayon::prelude::*;

use super::card::{ElementType, ModelCard, SizePolicy, Task};
use super::error::Result;
use super::model::Model;
use super::resize::resize_bilinear;
use super::runtime::{Device, RuntimeOptions};
use super::tensor::{Element, OutputMaps, Padding, Source, input_shape, write_item};
use crate::error::InferError;
use crate::matcher::{Disparity, StereoMatcher, check_same_size};

/// A stereo network run through ONNX Runtime, fed as its [`ModelCard`] says.
///
/// Dynamic-size models get the pair padded to the card's multiple and the
/// disparity cropped back; fixed-size models get the pair resized and the
/// disparity resized back and scaled by the width ratio. The card's sign
/// turns flow-style outputs into disparities. Pixels whose disparity is
/// negative or not finite are invalid (`+inf`, mask 0).
pub struct OnnxStereo {
    model: Model,
    name: String,
}

impl OnnxStereo {
    /// Opens `model` with a stereo `card`, checking the model's inputs and
    /// outputs against it.
    pub fn open(model: &Path, card: ModelCard, options: &RuntimeOptions) -> Result<OnnxStereo> {
        let name = format!("onnx:{}", card.name);
        Ok(OnnxStereo {
            model: Model::open(model, card, Task::Stereo, options)?,
            name,
        })
    }

    /// The model `bytes`, to be kept in `path`, with a stereo `card`, as
    /// [`OnnxStereo::open`].
    pub fn from_bytes(
        path: &Path,
        bytes: &[u8],
        card: ModelCard,
        options: &RuntimeOptions,
    ) -> Result<OnnxStereo> {
        let name = format!("onnx:{}", card.name);
        Ok(OnnxStereo {
            model: Model::from_bytes(path, bytes, card, Task::Stereo, options)?,
            name,
        })
    }

    /// The device the model runs on (the CPU after an allowed fallback).
    pub fn device(&self) -> Device {
        self.model.device()
    }

    /// The card the model is fed by.
    pub fn card(&self) -> &ModelCard {
        self.model.card()
    }

    /// Disparities of several pairs, in one run where the model takes a
    /// batch and the pairs share a size, else one run per pair.
    pub fn predict_batch(
        &self,
        pairs: &[(&RgbImage, &RgbImage)],
    ) -> std::result::Result<Vec<Disparity>, InferError> {
        for (left, right) in pairs {
            check_same_size(left, right)?;
        }
        let same_size = pairs
            .windows(2)
            .all(|w| w[0].0.dimensions() == w[1].0.dimensions());
        if pairs.len() > 1 && same_size && self.model.takes_batch(pairs.len()) {
            return self.run(pairs).map_err(backend);
        }
        pairs
            .iter()
            .map(|pair| {
                Ok(self
                    .run(std::slice::from_ref(pair))
                    .map_err(backend)?
                    .remove(0))
            })
            .collect()
    }

    /// One run over pairs of one size.
    fn run(&self, pairs: &[(&RgbImage, &RgbImage)]) -> Result<Vec<Disparity>> {
        let card = self.model.card();
        let size = pairs[0].0.dimensions();
        let resized;
        let (pairs, input_size) = match card.size {
            SizePolicy::Fixed { width, height } if (width, height) != size => {
                let resize =
                    |im: &RgbImage| imageops::resize(im, width, height, FilterType::Triangle);
                resized = pairs
                    .iter()
                    .map(|(l, r)| (resize(l), resize(r)))
                    .collect::<Vec<_>>();
                (
                    resized.iter().map(|(l, r)| (l, r)).collect::<Vec<_>>(),
                    (width, height),
                )
            }
            _ => (pairs.to_vec(), size),
        };
        let pad = Padding::for_card(input_size.0, input_size.1, &card.size);
        let maps = match card.dtype {
            ElementType::Float32 => self.infer::<f32>(&pairs, input_size, pad)?,
            ElementType::Uint8 => self.infer::<u8>(&pairs, input_size, pad)?,
        };
        let scale = card.output.sign * card.output.scale * size.0 as f32 / input_size.0 as f32;
        Ok(maps
            .into_iter()
            .map(|map| {
                let map = if input_size == size {
                    map
                } else {
                    resize_bilinear(&map, size.0, size.1)
                };
                to_disparity(map, scale)
            })
            .collect())
    }

    /// Builds the input tensors, runs the model and returns each pair's
    /// raw output map, padding removed.
    fn infer<T: Element>(
        &self,
        pairs: &[(&RgbImage, &RgbImage)],
        size: (u32, u32),
        pad: Padding,
    ) -> Result<Vec<FloatImage>> {
        let card = self.model.card();
        let (pw, ph) = pad.padded(size.0, size.1);
        let inputs = self.inputs::<T>(pairs, size, pad)?;
        let read = |dims: &[i64], data: &[T]| {
            let maps = OutputMaps::locate(dims, pairs.len(), (pw, ph)).ok_or_else(|| {
                self.model.run_error(format!(
                    "output {:?} has shape {dims:?}; expected {} map(s) of {pw}x{ph}",
                    card.output.name,
                    pairs.len()
                ))
            })?;
            let channel = card.output.channel;
            if channel >= maps.channels() {
                return Err(self.model.run_error(format!(
                    "the card reads channel {channel} of output {:?}, which has {}",
                    card.output.name,
                    maps.channels()
                )));
            }
            Ok((0..pairs.len())
                .map(|item| maps.crop(data, (item, channel), pw, pad, size))
                .collect())
        };
        self.model.run::<T, _>(inputs, read)
    }

    /// The model's input tensors (name, shape, values) for `pairs` of
    /// `size` padded by `pad`: one stacked 6-channel tensor, or a left and
    /// a right 3-channel one, as the card names them.
    fn inputs<T: Element>(
        &self,
        pairs: &[(&RgbImage, &RgbImage)],
        size: (u32, u32),
        pad: Padding,
    ) -> Result<Vec<Input<'_, T>>> {
        let card = self.model.card();
        let fill = match card.size {
            SizePolicy::Dynamic { fill, .. } => fill,
            SizePolicy::Fixed { .. } => Default::default(),
        };
        let padded = pad.padded(size.0, size.1);
        let plane = padded.0 as usize * padded.1 as usize;
        let shape = |channels: i64| input_shape(card.layout, pairs.len(), padded, channels);
        // One tensor from the views `which` picks of each pair (true = left).
        let fill_tensor = |which: &[bool]| {
            let channels = 3 * which.len();
            let mut data = vec![T::default(); pairs.len() * channels * plane];
            for (item, (l, r)) in data.chunks_mut(channels * plane).zip(pairs) {
                let sources: Vec<Source<'_>> = which
                    .iter()
                    .map(|&left| Source::rgb(if left { l } else { r }, card))
                    .collect();
                write_item(item, &sources, size, pad, fill, card.layout);
            }
            data
        };
        if let Some(name) = card.input("stacked") {
            return Ok(vec![(name, shape(6), fill_tensor(&[true, false]))]);
        }
        let missing = || {
            self.model
                .run_error("the card names neither stacked nor left and right inputs")
        };
        let left = card.input("left").ok_or_else(missing)?;
        let right = card.input("right").ok_or_else(missing)?;
        Ok(vec![
            (left, shape(3), fill_tensor(&[true])),
            (right, shape(3), fill_tensor(&[false])),
        ])
    }
}

/// One input tensor for [`Model::run`]: its name, shape and values.
type Input<'a, T> = (&'a str, Vec<i64>, Vec<T>);

/// Scales a raw output map and marks negative or non-finite values invalid.
fn to_disparity(mut map: FloatImage, scale: f32) -> Disparity {
    let mut valid = MaskImage::new(map.width(), map.height());
    map.par_iter_mut()
        .zip(valid.par_iter_mut())
        .for_each(|(d, v)| {
            let value = *d * scale;
            if value.is_finite() && value >= 0.0 {
                *d = value;
                *v = 255;
            } else {
                *d = f32::INFINITY;
            }
        });
    Disparity {
        disparity: map,
        valid,
    }
}

pub(super) fn backend(e: super::OnnxError) -> InferError {
    InferError::Backend(e.to_string())
}

impl StereoMatcher for OnnxStereo {
    fn name(&self) -> &str {
        &self.name
    }

    fn predict(
        &self,
        left: &RgbImage,
        right: &RgbImage,
    ) -> std::result::Result<Disparity, InferError> {
        let prediction = self.predict_batch(&[(left, right)])?.remove(0);
        crate::matcher::check_values(&self.name, &prediction.disparity)?;
        Ok(prediction)
    }
}
