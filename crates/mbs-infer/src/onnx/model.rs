//! A model session checked against its card, run under a lock (ort's
//! `Session::run` needs exclusive access).

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use ort::session::{Session, SessionInputValue};
use ort::value::{Outlet, Tensor, TensorElementType};

use super::card::{ElementType, Layout, ModelCard, SizePolicy, Task};
use super::error::{OnnxError, Result};
use super::runtime::{Device, RuntimeOptions, open_session, session_from_bytes};
use super::tensor::Element;

/// An ONNX model with its card.
pub struct Model {
    path: PathBuf,
    card: ModelCard,
    session: Mutex<Session>,
    device: Device,
    /// The batch size the model accepts; `None` = any.
    batch: Option<usize>,
}

impl Model {
    /// Opens `path` and checks its inputs and outputs against `card`, which
    /// must be for `task`.
    pub fn open(
        path: &Path,
        card: ModelCard,
        task: Task,
        options: &RuntimeOptions,
    ) -> Result<Model> {
        Self::check_task(&card, task)?;
        Self::checked(path, open_session(path, options)?, card)
    }

    /// The model `bytes`, to be kept in `path` (which errors name), checked
    /// as [`Model::open`] checks a file.
    pub fn from_bytes(
        path: &Path,
        bytes: &[u8],
        card: ModelCard,
        task: Task,
        options: &RuntimeOptions,
    ) -> Result<Model> {
        Self::check_task(&card, task)?;
        Self::checked(path, session_from_bytes(path, bytes, options)?, card)
    }

    /// Refuses a card for another task.
    fn check_task(card: &ModelCard, task: Task) -> Result<()> {
        if card.task != task {
            return Err(OnnxError::Card {
                card: card.name.clone(),
                message: format!(
                    "is a{} {} card; this needs a {} card",
                    if card.task == Task::Inpaint { "n" } else { "" },
                    card.task.noun(),
                    task.noun()
                ),
            });
        }
        Ok(())
    }

    /// `session` checked against `card`.
    fn checked(
        path: &Path,
        (session, device): (Session, Device),
        card: ModelCard,
    ) -> Result<Model> {
        let batch = check(&session, &card).map_err(|problem| OnnxError::CardMismatch {
            path: path.to_path_buf(),
            card: card.name.clone(),
            problem,
        })?;
        Ok(Model {
            path: path.to_path_buf(),
            card,
            session: Mutex::new(session),
            device,
            batch,
        })
    }

    /// The model's card.
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// The device the model runs on.
    pub fn device(&self) -> Device {
        self.device
    }

    /// The model file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether one run can take `n` items.
    pub fn takes_batch(&self, n: usize) -> bool {
        self.batch.is_none_or(|b| b == n)
    }

    /// Runs the model on `inputs` (tensor name, shape, values) and hands
    /// the card's output (shape, values) to `read`, without copying it.
    pub fn run<T: Element, R>(
        &self,
        inputs: Vec<(&str, Vec<i64>, Vec<T>)>,
        read: impl FnOnce(&[i64], &[T]) -> Result<R>,
    ) -> Result<R> {
        let values = inputs
            .into_iter()
            .map(|(name, shape, data)| {
                let tensor = Tensor::from_array((shape, data)).map_err(|e| self.run_error(e))?;
                Ok((Cow::from(name), SessionInputValue::from(tensor)))
            })
            .collect::<Result<Vec<_>>>()?;
        // A poisoned lock means a run panicked on another thread; the
        // session itself holds no state between runs.
        let mut session = self.session.lock().unwrap_or_else(|p| p.into_inner());
        let outputs = session.run(values).map_err(|e| self.run_error(e))?;
        let name = &self.card.output.name;
        let value = outputs
            .get(name)
            .ok_or_else(|| self.run_error(format!("no output {name}")))?;
        let (shape, data) = value
            .try_extract_tensor::<T>()
            .map_err(|e| self.run_error(e))?;
        read(shape, data)
    }

    /// An [`OnnxError::Run`] about this model.
    pub fn run_error(&self, message: impl std::fmt::Display) -> OnnxError {
        OnnxError::Run {
            path: self.path.clone(),
            message: message.to_string(),
        }
    }
}

/// The first disagreement between the session and the card, or the batch
/// size the model fixes (`None` = dynamic).
fn check(session: &Session, card: &ModelCard) -> std::result::Result<Option<usize>, String> {
    for input in session.inputs() {
        if !card.inputs.values().any(|n| n == input.name()) {
            return Err(format!(
                "the model's input {:?} is not in the card's inputs",
                input.name()
            ));
        }
    }
    let dtype = match card.dtype {
        ElementType::Float32 => TensorElementType::Float32,
        ElementType::Uint8 => TensorElementType::Uint8,
    };
    let mut batch = None;
    for (role, name) in &card.inputs {
        let outlet = session
            .inputs()
            .iter()
            .find(|o| o.name() == name)
            .ok_or_else(|| {
                format!(
                    "the card's {role} input {name:?} is not an input of the model (its inputs: {})",
                    outlet_names(session.inputs())
                )
            })?;
        let dims = tensor_dims(outlet, dtype)?;
        check_input_dims(card, role, name, &dims)?;
        // The last input with a fixed batch dimension sets the batch size.
        if let Ok(n) = usize::try_from(dims[0]) {
            batch = Some(n);
        }
    }
    check_output(session, card, dtype)?;
    Ok(batch)
}

/// The outlets' names, comma-separated, for messages.
fn outlet_names(outlets: &[Outlet]) -> String {
    outlets
        .iter()
        .map(|o| o.name().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Whether the declared dimensions `dims` of the card's `role` input
/// `name` agree with the card: rank 4 in its layout, the role's number of
/// channels, and its size policy.
fn check_input_dims(
    card: &ModelCard,
    role: &str,
    name: &str,
    dims: &[i64],
) -> std::result::Result<(), String> {
    let channels = match role {
        "stacked" => 6,
        "mask" => 1,
        _ => 3,
    };
    let (c, h, w) = match (card.layout, dims) {
        (Layout::Nchw, [_, c, h, w]) => (*c, *h, *w),
        (Layout::Nhwc, [_, h, w, c]) => (*c, *h, *w),
        _ => {
            return Err(format!(
                "input {name:?} has shape {dims:?}; the card expects rank 4 ({:?})",
                card.layout
            ));
        }
    };
    if c >= 0 && c != channels {
        return Err(format!(
            "input {name:?} has {c} channels ({:?} shape {dims:?}); the card's {role} input has {channels}",
            card.layout
        ));
    }
    match card.size {
        SizePolicy::Fixed { width, height } => {
            let fits = |d: i64, n: u32| d < 0 || d == i64::from(n);
            if !fits(w, width) || !fits(h, height) {
                return Err(format!(
                    "input {name:?} is {w}x{h} (width x height); the card says {width}x{height}"
                ));
            }
        }
        SizePolicy::Dynamic { .. } if w >= 0 || h >= 0 => {
            return Err(format!(
                "input {name:?} has a fixed size ({w}x{h}); the card says dynamic (use size.mode = fixed)"
            ));
        }
        SizePolicy::Dynamic { .. } => {}
    }
    Ok(())
}

/// Whether the model has the card's output, of element type `dtype` and
/// rank 2 to 4.
fn check_output(
    session: &Session,
    card: &ModelCard,
    dtype: TensorElementType,
) -> std::result::Result<(), String> {
    let output = &card.output.name;
    let outlet = session
        .outputs()
        .iter()
        .find(|o| o.name() == output)
        .ok_or_else(|| {
            format!(
                "the card's output {output:?} is not an output of the model (its outputs: {})",
                outlet_names(session.outputs())
            )
        })?;
    let dims = tensor_dims(outlet, dtype)?;
    if !(2..=4).contains(&dims.len()) {
        return Err(format!(
            "output {output:?} has shape {dims:?}; expected rank 2 to 4"
        ));
    }
    Ok(())
}

/// The declared dimensions of a tensor outlet of element type `dtype`
/// (`-1` = dynamic).
fn tensor_dims(outlet: &Outlet, dtype: TensorElementType) -> std::result::Result<Vec<i64>, String> {
    let ty = outlet.dtype();
    match (ty.tensor_type(), ty.tensor_shape()) {
        (Some(t), Some(shape)) if t == dtype => Ok(shape.to_vec()),
        (Some(t), _) => Err(format!(
            "{:?} holds {t:?} values; the card says {dtype:?}",
            outlet.name()
        )),
        _ => Err(format!("{:?} is not a tensor", outlet.name())),
    }
}
