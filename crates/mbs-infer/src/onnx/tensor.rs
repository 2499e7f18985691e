//! Images to input tensors and output tensors back to images, following a
//! model card: padding, layout, colour order, normalisation.

use mbs_core::{FloatImage, MaskImage, RgbImage};
use rayon::prelude::*;

use super::card::{ColorOrder, Layout, MaskSpec, ModelCard, PadMode, PadSide, SizePolicy};

/// Pixels added around an image before inference.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Padding {
    /// Columns added on the left.
    pub left: u32,
    /// Columns added on the right.
    pub right: u32,
    /// Rows added on top.
    pub top: u32,
    /// Rows added at the bottom.
    pub bottom: u32,
}

impl Padding {
    /// The padding that brings a `width` x `height` image to the card's
    /// multiple (none for fixed-size cards, whose inputs are resized).
    pub fn for_card(width: u32, height: u32, size: &SizePolicy) -> Padding {
        let SizePolicy::Dynamic {
            multiple,
            horizontal,
            vertical,
            ..
        } = *size
        else {
            return Padding::default();
        };
        let (left, right) = split(width.next_multiple_of(multiple) - width, horizontal);
        let (top, bottom) = split(height.next_multiple_of(multiple) - height, vertical);
        Padding {
            left,
            right,
            top,
            bottom,
        }
    }

    /// The padded size of a `width` x `height` image.
    pub fn padded(&self, width: u32, height: u32) -> (u32, u32) {
        (
            width + self.left + self.right,
            height + self.top + self.bottom,
        )
    }
}

fn split(total: u32, side: PadSide) -> (u32, u32) {
    match side {
        PadSide::Start => (total, 0),
        PadSide::End => (0, total),
        PadSide::Both => (total / 2, total - total / 2),
    }
}

/// An element type of model tensors.
pub trait Element:
    ort::value::PrimitiveTensorElementType + Copy + Default + std::fmt::Debug + Send + Sync + 'static
{
    /// The nearest value of this type.
    fn from_f32(v: f32) -> Self;
    /// The value as a float.
    fn to_f32(self) -> f32;
}

impl Element for f32 {
    fn from_f32(v: f32) -> f32 {
        v
    }
    fn to_f32(self) -> f32 {
        self
    }
}

impl Element for u8 {
    fn from_f32(v: f32) -> u8 {
        v.round().clamp(0.0, 255.0) as u8
    }
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
}

/// One image going into a tensor: its raw channels and the value each of
/// the 256 levels of each channel becomes.
pub struct Source<'a> {
    /// Interleaved 8-bit pixels, `channels` per pixel, row-major.
    raw: &'a [u8],
    /// Channels per pixel of `raw`.
    channels: usize,
    /// Per tensor channel: (channel of `raw`, level -> value).
    maps: Vec<(usize, [f32; 256])>,
    /// Value of zero-filled padding, per tensor channel.
    zero: f32,
}

impl<'a> Source<'a> {
    /// A colour image normalised as the card says, in its colour order.
    pub fn rgb(image: &'a RgbImage, card: &ModelCard) -> Source<'a> {
        let order = match card.color_order {
            ColorOrder::Rgb => [0, 1, 2],
            ColorOrder::Bgr => [2, 1, 0],
        };
        let maps = (0..3)
            .map(|c| {
                let level = |v: usize| (v as f32 * card.scale - card.mean[c]) / card.std[c];
                (order[c], std::array::from_fn(level))
            })
            .collect();
        Source {
            raw: image.as_raw(),
            channels: 3,
            maps,
            zero: 0.0,
        }
    }

    /// A hole mask (non-zero = fill) as the card's hole and keep values.
    pub fn mask(mask: &'a MaskImage, spec: MaskSpec) -> Source<'a> {
        let level = |v: usize| if v == 0 { spec.keep } else { spec.hole };
        Source {
            raw: mask.as_raw(),
            channels: 1,
            maps: vec![(0, std::array::from_fn(level))],
            zero: spec.keep,
        }
    }

    /// Number of tensor channels this source fills.
    pub fn channels(&self) -> usize {
        self.maps.len()
    }
}

/// Writes one batch item from `sources` (their channels one after the
/// other) of size `width` x `height`, padded by `pad`, into `out`, which
/// holds `channels * padded width * padded height` values in `layout`.
/// Rows are written in parallel.
pub fn write_item<T: Element>(
    out: &mut [T],
    sources: &[Source<'_>],
    (width, height): (u32, u32),
    pad: Padding,
    fill: PadMode,
    layout: Layout,
) {
    let (pw, ph) = pad.padded(width, height);
    let (pw, ph) = (pw as usize, ph as usize);
    let planes = tensor_planes::<T>(sources);
    let framing = Framing {
        width: width as usize,
        height,
        pad,
        fill,
    };
    match layout {
        Layout::Nchw => out.par_chunks_mut(pw).enumerate().for_each(|(i, dst)| {
            framing.write_nchw_row(dst, &planes[i / ph], i % ph);
        }),
        Layout::Nhwc => out
            .par_chunks_mut(pw * planes.len())
            .enumerate()
            .for_each(|(y, dst)| framing.write_nhwc_row(dst, &planes, y)),
    }
}

/// The shape of an input tensor of `batch` items with `channels` channels
/// of `width` x `height` (padded) pixels each, in `layout`.
pub fn input_shape(
    layout: Layout,
    batch: usize,
    (width, height): (u32, u32),
    channels: i64,
) -> Vec<i64> {
    let (n, h, w) = (batch as i64, i64::from(height), i64::from(width));
    match layout {
        Layout::Nchw => vec![n, channels, h, w],
        Layout::Nhwc => vec![n, h, w, channels],
    }
}

/// One tensor channel: its source, the source's channel, the lookup table
/// (level -> tensor value) and the padding value.
type Plane<'s, 'a, T> = (&'s Source<'a>, usize, [T; 256], T);

/// The tensor channels of `sources`, one after the other, with their
/// lookup tables in the tensor's element type.
fn tensor_planes<'s, 'a, T: Element>(sources: &'s [Source<'a>]) -> Vec<Plane<'s, 'a, T>> {
    sources
        .iter()
        .flat_map(|s| {
            s.maps.iter().map(move |(raw_channel, map)| {
                let lut = std::array::from_fn(|v| T::from_f32(map[v]));
                (s, *raw_channel, lut, T::from_f32(s.zero))
            })
        })
        .collect()
}

/// Where an item's pixels sit in its padded frame, and how the padding is
/// filled.
struct Framing {
    /// The item's width, in pixels.
    width: usize,
    /// The item's height, in pixels.
    height: u32,
    /// The padding around it.
    pad: Padding,
    /// How the padding is filled.
    fill: PadMode,
}

impl Framing {
    /// The source row of padded row `y`; `None` = zero padding.
    #[inline]
    fn source_row(&self, y: usize) -> Option<usize> {
        let y = y as i64 - i64::from(self.pad.top);
        match self.fill {
            PadMode::Replicate => Some(y.clamp(0, i64::from(self.height) - 1) as usize),
            PadMode::Zero => (0..i64::from(self.height))
                .contains(&y)
                .then_some(y as usize),
        }
    }

    /// Writes padded row `y` of one channel `plane` into `dst` (NCHW: one
    /// channel's row is contiguous).
    #[inline]
    fn write_nchw_row<T: Element>(&self, dst: &mut [T], plane: &Plane<'_, '_, T>, y: usize) {
        let (source, raw_channel, lut, zero) = plane;
        let w = self.width;
        let Some(sy) = self.source_row(y) else {
            dst.fill(*zero);
            return;
        };
        let stride = source.channels;
        let row = &source.raw[sy * w * stride..][..w * stride];
        let (before, rest) = dst.split_at_mut(self.pad.left as usize);
        let (middle, after) = rest.split_at_mut(w);
        for (d, px) in middle.iter_mut().zip(row.chunks_exact(stride)) {
            *d = lut[usize::from(px[*raw_channel])];
        }
        let (first, last) = match self.fill {
            PadMode::Replicate => (middle[0], middle[w - 1]),
            PadMode::Zero => (*zero, *zero),
        };
        before.fill(first);
        after.fill(last);
    }

    /// Writes padded row `y` of every channel in `planes` into `dst` (NHWC:
    /// the channels of a pixel are interleaved).
    #[inline]
    fn write_nhwc_row<T: Element>(&self, dst: &mut [T], planes: &[Plane<'_, '_, T>], y: usize) {
        let (w, left, channels) = (self.width, self.pad.left as usize, planes.len());
        for (c, (source, raw_channel, lut, zero)) in planes.iter().enumerate() {
            let stride = source.channels;
            let row = self
                .source_row(y)
                .map(|sy| &source.raw[sy * w * stride..][..w * stride]);
            for (x, d) in dst.iter_mut().skip(c).step_by(channels).enumerate() {
                let sx = x as i64 - left as i64;
                let sx = match self.fill {
                    PadMode::Replicate => Some(sx.clamp(0, w as i64 - 1) as usize),
                    PadMode::Zero => (0..w as i64).contains(&sx).then_some(sx as usize),
                };
                *d = match (row, sx) {
                    (Some(row), Some(sx)) => lut[usize::from(row[sx * stride + raw_channel])],
                    _ => *zero,
                };
            }
        }
    }
}

/// Where the maps of one batch item lie in an output tensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutputMaps {
    /// Offset between consecutive channels.
    channel_stride: usize,
    /// Offset between consecutive pixels of a row.
    pixel_stride: usize,
    /// Offset between consecutive batch items.
    item_stride: usize,
    /// Number of channels.
    channels: usize,
}

impl OutputMaps {
    /// Locates `width` x `height` maps in a tensor of shape `dims`: rank 4
    /// NCHW or NHWC (told apart by where the size sits), rank 3 (N, H, W)
    /// or rank 2 (H, W). `None` when no such map fits the shape.
    pub fn locate(dims: &[i64], batch: usize, (width, height): (u32, u32)) -> Option<OutputMaps> {
        let (w, h) = (i64::from(width), i64::from(height));
        let plane = (width as usize) * (height as usize);
        let positive = |d: i64| usize::try_from(d).ok();
        let maps = match *dims {
            [n, c, hh, ww] if hh == h && ww == w => OutputMaps {
                channel_stride: plane,
                pixel_stride: 1,
                item_stride: positive(c)? * plane,
                channels: positive(c)?,
            }
            .with_batch(n, batch)?,
            [n, hh, ww, c] if hh == h && ww == w => OutputMaps {
                channel_stride: 1,
                pixel_stride: positive(c)?,
                item_stride: positive(c)? * plane,
                channels: positive(c)?,
            }
            .with_batch(n, batch)?,
            [n, hh, ww] if hh == h && ww == w => OutputMaps {
                channel_stride: plane,
                pixel_stride: 1,
                item_stride: plane,
                channels: 1,
            }
            .with_batch(n, batch)?,
            [hh, ww] if hh == h && ww == w && batch == 1 => OutputMaps {
                channel_stride: plane,
                pixel_stride: 1,
                item_stride: plane,
                channels: 1,
            },
            _ => return None,
        };
        Some(maps)
    }

    fn with_batch(self, n: i64, batch: usize) -> Option<OutputMaps> {
        (usize::try_from(n).ok()? == batch).then_some(self)
    }

    /// Number of channels per item.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Channel `channel` of item `item` without its padding: the
    /// `width` x `height` image at (`pad.left`, `pad.top`) of maps
    /// `padded_width` wide, as floats (rows in parallel).
    pub fn crop<T: Element>(
        &self,
        data: &[T],
        (item, channel): (usize, usize),
        padded_width: u32,
        pad: Padding,
        (width, height): (u32, u32),
    ) -> FloatImage {
        let start = item * self.item_stride + channel * self.channel_stride;
        let (pw, w, step) = (padded_width as usize, width as usize, self.pixel_stride);
        let mut out = vec![0.0; w * height as usize];
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            let first = start + ((y + pad.top as usize) * pw + pad.left as usize) * step;
            for (x, v) in row.iter_mut().enumerate() {
                *v = data[first + x * step].to_f32();
            }
        });
        FloatImage::from_raw(width, height, out).expect("one value per pixel by construction")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn card(size: &str) -> ModelCard {
        ModelCard::from_json(
            "test",
            &format!(
                r#"{{"name": "t", "task": "stereo", "inputs": {{"left": "l", "right": "r"}},
                    "scale": 0.5, "mean": [1, 2, 3], "std": [1, 2, 4], "color_order": "BGR",
                    "size": {size}, "output": {{"name": "d"}}}}"#
            ),
        )
        .unwrap()
    }

    #[test]
    fn padding_reaches_the_multiple_on_the_chosen_sides() {
        let size = card(
            r#"{"mode": "dynamic", "multiple": 8, "horizontal": "both", "vertical": "start"}"#,
        )
        .size;
        let pad = Padding::for_card(13, 9, &size);
        assert_eq!(
            pad,
            Padding {
                left: 1,
                right: 2,
                top: 7,
                bottom: 0
            }
        );
        assert_eq!(pad.padded(13, 9), (16, 16));
        let fixed = card(r#"{"mode": "fixed", "width": 4, "height": 4}"#).size;
        assert_eq!(Padding::for_card(13, 9, &fixed), Padding::default());
    }

    #[test]
    fn items_are_normalised_reordered_and_padded() {
        let card = card(r#"{"mode": "dynamic", "multiple": 1}"#);
        let image = RgbImage::from_raw(2, 1, vec![10, 20, 30, 40, 50, 60]).unwrap();
        let source = [Source::rgb(&image, &card)];
        let pad = Padding {
            left: 1,
            ..Padding::default()
        };
        let mut nchw = vec![0f32; 9];
        write_item(
            &mut nchw,
            &source,
            (2, 1),
            pad,
            PadMode::Replicate,
            Layout::Nchw,
        );
        // BGR: channel 0 is blue, (30 * 0.5 - 1) / 1 = 14; replicated left.
        assert_eq!(nchw, [14.0, 14.0, 29.0, 4.0, 4.0, 11.5, 0.5, 0.5, 4.25]);
        let mut nhwc = vec![0f32; 9];
        write_item(&mut nhwc, &source, (2, 1), pad, PadMode::Zero, Layout::Nhwc);
        assert_eq!(nhwc, [0.0, 0.0, 0.0, 14.0, 4.0, 0.5, 29.0, 11.5, 4.25]);
    }

    #[test]
    fn output_maps_are_found_in_either_layout() {
        let nchw = OutputMaps::locate(&[2, 2, 3, 4], 2, (4, 3)).unwrap();
        let data: Vec<f32> = (0..48).map(|v| v as f32).collect();
        let pad = Padding {
            left: 1,
            top: 1,
            ..Padding::default()
        };
        let crop = nchw.crop(&data, (1, 1), 4, pad, (2, 2));
        assert_eq!(crop.as_raw(), &[41.0, 42.0, 45.0, 46.0]);
        let nhwc = OutputMaps::locate(&[1, 3, 4, 2], 1, (4, 3)).unwrap();
        let crop = nhwc.crop(&data, (0, 1), 4, Padding::default(), (4, 3));
        assert_eq!(crop.as_raw()[..2], [1.0, 3.0]);
        assert!(OutputMaps::locate(&[1, 1, 5, 4], 1, (4, 3)).is_none());
        assert!(OutputMaps::locate(&[3, 4], 1, (4, 3)).is_some());
    }
}
