//! Stereo matching and inpainting behind traits, with built-in defaults and ONNX models.

pub mod inpaint;
