//! Model cards: how to feed an ONNX model and read its output (JSON, schema
//! `schemas/model-card.schema.json`).
//!
//! A card names the model's input tensors by role (`left`/`right` or
//! `stacked` for stereo, `image`/`mask` for inpainting), their layout, colour
//! order, element type and normalisation (`(value * scale - mean) / std`,
//! value in 0..=255), the size policy (any size padded to a multiple, or one
//! fixed size), the output tensor and its sign or scale, and for inpainting
//! the values that mark holes and kept pixels.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::error::{OnnxError, Result};
use crate::DepthKind;

/// What a model does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Task {
    /// A rectified pair in, a disparity on the left view's grid out.
    Stereo,
    /// An image and a hole mask in, the filled image out.
    Inpaint,
    /// One image in, a map of its depth or inverse depth out
    /// ([`OutputSpec::kind`] says which).
    Depth,
}

impl Task {
    /// The task as a noun for messages.
    pub fn noun(self) -> &'static str {
        match self {
            Task::Stereo => "stereo",
            Task::Inpaint => "inpainting",
            Task::Depth => "monocular depth",
        }
    }
}

/// Memory order of an image tensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Layout {
    /// Batch, channels, rows, columns.
    #[default]
    #[serde(rename = "NCHW")]
    Nchw,
    /// Batch, rows, columns, channels.
    #[serde(rename = "NHWC")]
    Nhwc,
}

/// Channel order of colour tensors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ColorOrder {
    /// Red, green, blue.
    #[default]
    #[serde(rename = "RGB")]
    Rgb,
    /// Blue, green, red (OpenCV-trained models).
    #[serde(rename = "BGR")]
    Bgr,
}

/// Element type of the input and output tensors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ElementType {
    /// 32-bit floats, normalised by the card.
    #[default]
    Float32,
    /// Raw 8-bit values (scale 1, mean 0, std 1).
    Uint8,
}

/// Where padding goes along one axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PadSide {
    /// Before the image (left or top).
    Start,
    /// After the image (right or bottom).
    #[default]
    End,
    /// Split in two, the larger half after.
    Both,
}

/// How padded pixels are filled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PadMode {
    /// Copies of the nearest edge pixel.
    #[default]
    Replicate,
    /// Zero in the normalised tensor.
    Zero,
}

/// Which sizes the model accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "lowercase", deny_unknown_fields)]
pub enum SizePolicy {
    /// Any size whose sides are multiples of `multiple`: inputs are padded
    /// and outputs cropped back.
    Dynamic {
        /// Sides must be multiples of this (1 = any size).
        multiple: u32,
        /// Where horizontal padding goes.
        #[serde(default)]
        horizontal: PadSide,
        /// Where vertical padding goes.
        #[serde(default)]
        vertical: PadSide,
        /// How padded pixels are filled.
        #[serde(default)]
        fill: PadMode,
    },
    /// Exactly one size: stereo inputs are resized (and disparities scaled
    /// by the width ratio); inpainting works on a window around the holes.
    Fixed {
        /// Width of the model's input, pixels.
        width: u32,
        /// Height of the model's input, pixels.
        height: u32,
    },
}

/// The output tensor and how to read it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Tensor name.
    pub name: String,
    /// Stereo: +1 if the model outputs disparity, -1 if it outputs the
    /// horizontal flow (negative disparity, e.g. RAFT-Stereo).
    #[serde(default = "one")]
    pub sign: f32,
    /// Multiplier to pixels of disparity (stereo) or to 0..=255 (inpainting).
    #[serde(default = "one")]
    pub scale: f32,
    /// Stereo: which channel holds the disparity when there are several
    /// (CREStereo outputs the flow's x and y).
    #[serde(default)]
    pub channel: usize,
    /// Depth: what the map holds (required for depth cards, refused on
    /// the others).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kind: Option<DepthKind>,
}

/// Inpainting: the mask values the model expects.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaskSpec {
    /// Value of pixels to fill (LaMa: 1.0; MI-GAN: 0).
    pub hole: f32,
    /// Value of pixels to keep (LaMa: 0.0; MI-GAN: 255).
    pub keep: f32,
}

/// How to feed one ONNX model (see the module documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelCard {
    /// Short name (`lama`, `crestereo`).
    pub name: String,
    /// What the model does.
    pub task: Task,
    /// Where the conventions come from (export repository, paper).
    #[serde(default)]
    pub notes: String,
    /// Input tensor names by role: `left` and `right`, or `stacked` (left
    /// channels then right channels in one tensor), for stereo; `image` and
    /// `mask` for inpainting.
    pub inputs: BTreeMap<String, String>,
    /// Memory order of image tensors.
    #[serde(default)]
    pub layout: Layout,
    /// Channel order of colour tensors.
    #[serde(default)]
    pub color_order: ColorOrder,
    /// Element type of inputs and outputs.
    #[serde(default)]
    pub dtype: ElementType,
    /// Multiplier applied to 0..=255 pixel values before `mean` and `std`.
    #[serde(default = "one")]
    pub scale: f32,
    /// Per-channel mean subtracted after scaling (in `color_order`).
    #[serde(default = "zeros")]
    pub mean: [f32; 3],
    /// Per-channel standard deviation divided by last (in `color_order`).
    #[serde(default = "ones")]
    pub std: [f32; 3],
    /// Which sizes the model accepts.
    pub size: SizePolicy,
    /// The output tensor.
    pub output: OutputSpec,
    /// Inpainting: mask values.
    #[serde(default)]
    pub mask: Option<MaskSpec>,
}

fn one() -> f32 {
    1.0
}
fn zeros() -> [f32; 3] {
    [0.0; 3]
}
fn ones() -> [f32; 3] {
    [1.0; 3]
}

/// Cards shipped with mbs: `(name, JSON)`.
const BUILTIN: &[(&str, &str)] = &[
    ("lama", include_str!("../../models/cards/lama.json")),
    ("migan", include_str!("../../models/cards/migan.json")),
    (
        "crestereo",
        include_str!("../../models/cards/crestereo.json"),
    ),
    ("hitnet", include_str!("../../models/cards/hitnet.json")),
    (
        "raft-stereo",
        include_str!("../../models/cards/raft-stereo.json"),
    ),
    ("igev", include_str!("../../models/cards/igev.json")),
    (
        "fastdepth",
        include_str!("../../models/cards/fastdepth.json"),
    ),
    (
        "depth-anything-v2-small",
        include_str!("../../models/cards/depth-anything-v2-small.json"),
    ),
    (
        "depth-anything-v2-base",
        include_str!("../../models/cards/depth-anything-v2-base.json"),
    ),
    (
        "depth-anything-v2-large",
        include_str!("../../models/cards/depth-anything-v2-large.json"),
    ),
    (
        "midas-v21-small",
        include_str!("../../models/cards/midas-v21-small.json"),
    ),
];

impl ModelCard {
    /// The names of the built-in cards.
    pub fn builtin_names() -> impl Iterator<Item = &'static str> {
        BUILTIN.iter().map(|(name, _)| *name)
    }

    /// A built-in card by name, or a card file when `name_or_file` ends in
    /// `.json` or names an existing file.
    pub fn load(name_or_file: &str) -> Result<ModelCard> {
        if let Some((_, json)) = BUILTIN.iter().find(|(name, _)| *name == name_or_file) {
            return ModelCard::from_json(name_or_file, json);
        }
        let path = Path::new(name_or_file);
        if name_or_file.ends_with(".json") || path.is_file() {
            return ModelCard::from_file(path);
        }
        Err(OnnxError::Card {
            card: name_or_file.into(),
            message: format!(
                "no built-in card of that name (built-in: {}) and no such .json file",
                ModelCard::builtin_names().collect::<Vec<_>>().join(", ")
            ),
        })
    }

    /// Reads and checks a card file.
    pub fn from_file(path: &Path) -> Result<ModelCard> {
        let json = mbs_core::regular::read_text(path).map_err(|e| OnnxError::Card {
            card: path.display().to_string(),
            message: format!("cannot read: {}", e.reason()),
        })?;
        ModelCard::from_json(&path.display().to_string(), &json)
    }

    /// Parses and checks a card; `origin` names it in errors.
    pub fn from_json(origin: &str, json: &str) -> Result<ModelCard> {
        let card: ModelCard = serde_json::from_str(json).map_err(|e| OnnxError::Card {
            card: origin.into(),
            message: e.to_string(),
        })?;
        card.check().map_err(|message| OnnxError::Card {
            card: origin.into(),
            message,
        })?;
        Ok(card)
    }

    /// The tensor name of an input role, if the card has it.
    pub fn input(&self, role: &str) -> Option<&str> {
        self.inputs.get(role).map(String::as_str)
    }

    /// The first inconsistency of the card, if any.
    fn check(&self) -> std::result::Result<(), String> {
        let roles: Vec<&str> = self.inputs.keys().map(String::as_str).collect();
        let expected: &[&[&str]] = match self.task {
            Task::Stereo => &[&["left", "right"], &["stacked"]],
            Task::Inpaint => &[&["image", "mask"]],
            Task::Depth => &[&["image"]],
        };
        if !expected.contains(&roles.as_slice()) {
            return Err(format!(
                "inputs has roles {roles:?}; a {} card needs one of {expected:?}",
                self.task.noun()
            ));
        }
        if self.std.contains(&0.0) {
            return Err("std has a zero".into());
        }
        if self.dtype == ElementType::Uint8
            && (self.scale != 1.0 || self.mean != [0.0; 3] || self.std != [1.0; 3])
        {
            return Err("a uint8 model takes raw pixels: scale 1, mean 0, std 1".into());
        }
        match self.size {
            SizePolicy::Dynamic { multiple: 0, .. } => {
                return Err("size.multiple must be at least 1".into());
            }
            SizePolicy::Fixed { width, height } if width == 0 || height == 0 => {
                return Err("a fixed size must be at least 1x1".into());
            }
            _ => {}
        }
        if self.output.sign.abs() != 1.0 {
            return Err(format!(
                "output.sign is {}; expected 1 or -1",
                self.output.sign
            ));
        }
        match (self.task, self.output.kind) {
            (Task::Depth, None) => {
                return Err(
                    "a depth card needs output.kind: metric-depth, inverse-relative \
                            or disparity"
                        .into(),
                );
            }
            (Task::Stereo | Task::Inpaint, Some(_)) => {
                return Err(format!("a {} card has no output.kind", self.task.noun()));
            }
            _ => {}
        }
        match (self.task, self.mask) {
            (Task::Inpaint, None) => Err("an inpaint card needs mask.hole and mask.keep".into()),
            (Task::Inpaint, Some(m)) if m.hole == m.keep => {
                Err("mask.hole and mask.keep are equal".into())
            }
            (Task::Stereo | Task::Depth, Some(_)) => {
                Err(format!("a {} card has no mask", self.task.noun()))
            }
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_cards_parse_and_check() {
        for name in ModelCard::builtin_names() {
            let card = ModelCard::load(name).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(card.name, name);
            assert!(!card.notes.is_empty(), "{name} says what it is based on");
        }
        assert_eq!(ModelCard::load("raft-stereo").unwrap().output.sign, -1.0);
        let lama = ModelCard::load("lama").unwrap();
        assert_eq!(
            lama.mask,
            Some(MaskSpec {
                hole: 1.0,
                keep: 0.0
            })
        );
        assert_eq!(
            lama.size,
            SizePolicy::Fixed {
                width: 512,
                height: 512
            }
        );
        let migan = ModelCard::load("migan").unwrap();
        assert_eq!(
            migan.mask,
            Some(MaskSpec {
                hole: 0.0,
                keep: 255.0
            })
        );
        assert_eq!(migan.dtype, ElementType::Uint8);
    }

    #[test]
    fn a_depth_card_takes_one_image_and_says_what_its_output_is() {
        let card = |output: &str, inputs: &str| {
            format!(
                r#"{{"name": "t", "task": "depth", "inputs": {inputs},
                   "size": {{"mode": "fixed", "width": 224, "height": 224}}, "output": {output}}}"#
            )
        };
        let image = r#"{"image": "0"}"#;
        let parsed = ModelCard::from_json(
            "ok",
            &card(r#"{"name": "d", "kind": "inverse-relative"}"#, image),
        );
        assert_eq!(
            parsed.unwrap().output.kind,
            Some(DepthKind::InverseRelative)
        );
        let err = |output: &str, inputs: &str| {
            ModelCard::from_json("d.json", &card(output, inputs))
                .unwrap_err()
                .to_string()
        };
        assert!(err(r#"{"name": "d"}"#, image).contains("a depth card needs output.kind"));
        assert!(err(r#"{"name": "d", "kind": "depth"}"#, image).contains("unknown variant"));
        let two = r#"{"image": "0", "mask": "1"}"#;
        assert!(err(r#"{"name": "d", "kind": "disparity"}"#, two).contains("inputs has roles"));
        let fastdepth = ModelCard::load("fastdepth").unwrap();
        assert_eq!(fastdepth.output.kind, Some(DepthKind::MetricDepth));
        assert_eq!(
            fastdepth.size,
            SizePolicy::Fixed {
                width: 224,
                height: 224
            }
        );
    }

    /// The ImageNet mean and standard deviation.
    const IMAGENET: [[f32; 3]; 2] = [[0.485, 0.456, 0.406], [0.229, 0.224, 0.225]];

    /// Checks that the built-in card `name` takes RGB / 255 normalised by
    /// `[mean, std]` into tensor `io.0` as a fixed `side` x `side` NCHW
    /// float32 image, gives an inverse relative depth in tensor `io.1`, and
    /// names `licence` in its notes.
    fn assert_relative_depth(
        name: &str,
        io: (&str, &str),
        side: u32,
        norm: [[f32; 3]; 2],
        licence: &str,
    ) {
        let card = ModelCard::load(name).unwrap();
        assert_eq!(card.task, Task::Depth, "{name}");
        let kind = Some(DepthKind::InverseRelative);
        assert_eq!(
            (card.input("image"), card.output.kind),
            (Some(io.0), kind),
            "{name}"
        );
        assert_eq!(card.output.name, io.1, "{name}");
        let fixed = SizePolicy::Fixed {
            width: side,
            height: side,
        };
        assert_eq!(card.size, fixed, "{name}");
        assert_eq!(
            (card.layout, card.color_order),
            (Layout::Nchw, ColorOrder::Rgb),
            "{name}"
        );
        assert_eq!(card.dtype, ElementType::Float32, "{name}");
        assert!((card.scale * 255.0 - 1.0).abs() < 1e-6, "{name}: RGB / 255");
        assert_eq!([card.mean, card.std], norm, "{name}");
        assert_eq!((card.output.sign, card.output.scale), (1.0, 1.0), "{name}");
        assert!(card.notes.contains(licence), "{name} states its licence");
    }

    /// The conventions each relative depth card's notes cite (see
    /// docs/depth-models.md): an edit that changes one fails here.
    #[test]
    fn relative_depth_cards_keep_their_sources_conventions() {
        let da = ("image", "depth");
        assert_relative_depth("depth-anything-v2-small", da, 518, IMAGENET, "Apache-2.0");
        assert_relative_depth("depth-anything-v2-base", da, 518, IMAGENET, "CC-BY-NC-4.0");
        assert_relative_depth("depth-anything-v2-large", da, 518, IMAGENET, "CC-BY-NC-4.0");
        // MiDaS's ONNX export normalises inside the graph: RGB in 0..1 only.
        let none = [[0.0; 3], [1.0; 3]];
        assert_relative_depth("midas-v21-small", ("0", "797"), 256, none, "MIT");
    }

    #[test]
    fn unknown_names_list_the_builtins() {
        let err = ModelCard::load("nope").unwrap_err().to_string();
        assert!(err.contains("nope") && err.contains("crestereo"), "{err}");
    }

    #[test]
    fn inconsistent_cards_are_refused_with_the_reason() {
        let card = |patch: &str| {
            format!(
                r#"{{"name": "t", "task": "stereo", "inputs": {{"left": "l", "right": "r"}},
                   "size": {{"mode": "dynamic", "multiple": 8}}, "output": {{"name": "d"}} {patch}}}"#
            )
        };
        assert!(ModelCard::from_json("ok", &card("")).is_ok());
        let err = |patch: &str| {
            ModelCard::from_json("x.json", &card(patch))
                .unwrap_err()
                .to_string()
        };
        assert!(err(r#", "std": [1, 0, 1]"#).contains("std has a zero"));
        assert!(err(r#", "mask": {"hole": 1, "keep": 0}"#).contains("no mask"));
        assert!(err(r#", "colour": "RGB""#).contains("unknown field"));
        let stereo_kind = ModelCard::from_json(
            "k.json",
            &card("").replace(r#""name": "d""#, r#""name": "d", "kind": "disparity""#),
        )
        .unwrap_err()
        .to_string();
        assert!(
            stereo_kind.contains("a stereo card has no output.kind"),
            "{stereo_kind}"
        );
        let wrong_roles = ModelCard::from_json(
            "y.json",
            &card("").replace(r#""left": "l""#, r#""image": "l""#),
        )
        .unwrap_err()
        .to_string();
        assert!(
            wrong_roles.starts_with("model card y.json: inputs has roles"),
            "{wrong_roles}"
        );
    }
}
