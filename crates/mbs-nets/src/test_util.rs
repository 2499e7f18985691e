//! Helpers shared by the unit tests: tensors from slices and back.

use burn::tensor::{Device, Tensor, TensorData};

/// A `[B, C, H, W]` tensor from row-major values.
pub fn tensor4(data: &[f32], shape: [usize; 4], device: &Device) -> Tensor<4> {
    Tensor::from_data(TensorData::new(data.to_vec(), shape), device)
}

/// The values of a tensor, row-major.
pub fn values<const D: usize>(tensor: Tensor<D>) -> Vec<f32> {
    tensor
        .into_data()
        .try_to_vec::<f32>()
        .expect("test tensors are f32")
}

/// Element-wise `|got - want| <= tolerance`, with the first offender named.
pub fn assert_close(got: &[f32], want: &[f32], tolerance: f32) {
    assert_eq!(got.len(), want.len(), "lengths differ");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= tolerance,
            "element {i}: got {g}, want {w} (tolerance {tolerance})"
        );
    }
}

/// Every float parameter of a module, flattened in visiting order.
#[derive(Default)]
pub struct FlatParams(pub Vec<f32>);

impl burn::module::ModuleVisitor for FlatParams {
    fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<Tensor<D>>) {
        self.0.extend(values(param.val().without_autodiff()));
    }
}

/// Parity fixtures of the official networks (`testdata/parity`, made by
/// `tools/parity/*_fixtures.py`).
pub mod parity {
    use std::collections::BTreeMap;
    use std::path::{Path, PathBuf};

    use burn::tensor::{Device, Tensor, TensorData};
    use serde_json::Value;

    use super::values;
    use crate::official::{StateDict, StateTensor};
    use crate::seeded::seeded_tensor;

    /// Largest difference allowed to the official output (pixels).
    pub const TOLERANCE_PX: f32 = 1e-3;

    /// `testdata/parity/<stem>.safetensors`.
    pub fn fixture_path(stem: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../testdata/parity")
            .join(format!("{stem}.safetensors"))
    }

    /// The fixture's tensors and its metadata (`config`, `state_dict` shapes).
    pub fn fixture(stem: &str) -> (StateDict, Value, BTreeMap<String, Vec<usize>>) {
        let path = fixture_path(stem);
        let bytes = std::fs::read(&path).expect("fixture is in testdata/parity");
        let (_, metadata) = safetensors::SafeTensors::read_metadata(&bytes).expect("safetensors");
        let metadata = metadata.metadata().clone().expect("fixture metadata");
        let config = serde_json::from_str(&metadata["config"]).expect("config JSON");
        let shapes = serde_json::from_str(&metadata["state_dict"]).expect("state_dict JSON");
        (StateDict::read(&path).expect("readable"), config, shapes)
    }

    /// The seeded state dict over the official keys (counters excepted).
    pub fn seeded_dict(shapes: &BTreeMap<String, Vec<usize>>) -> StateDict {
        StateDict {
            tensors: shapes
                .iter()
                .filter(|(key, _)| !key.ends_with("num_batches_tracked"))
                .map(|(key, shape)| {
                    let values = seeded_tensor(key, shape).expect("seeded rule covers the key");
                    (
                        key.clone(),
                        StateTensor {
                            shape: shape.clone(),
                            values,
                        },
                    )
                })
                .collect(),
        }
    }

    /// Asserts that an export (`export_state_dict`) has exactly the official
    /// keys with their shapes.
    pub fn assert_official_keys(
        export: &(StateDict, Vec<String>),
        shapes: &BTreeMap<String, Vec<usize>>,
    ) {
        let (exported, counters) = export;
        let mut ours: BTreeMap<String, Vec<usize>> = exported
            .tensors
            .iter()
            .map(|(k, t)| (k.clone(), t.shape.clone()))
            .collect();
        ours.extend(counters.iter().map(|k| (k.clone(), vec![])));
        let missing: Vec<_> = shapes.keys().filter(|k| !ours.contains_key(*k)).collect();
        let extra: Vec<_> = ours.keys().filter(|k| !shapes.contains_key(*k)).collect();
        assert!(
            missing.is_empty() && extra.is_empty(),
            "missing {missing:?}, extra {extra:?}"
        );
        for (key, shape) in shapes {
            assert_eq!(&ours[key], shape, "{key}");
        }
    }

    /// A 4-D tensor of the fixture.
    pub fn input(dict: &StateDict, key: &str, device: &Device) -> Tensor<4> {
        let t = &dict.tensors[key];
        let shape: [usize; 4] = t.shape.clone().try_into().expect("4-D");
        Tensor::from_data(TensorData::new(t.values.clone(), shape), device)
    }

    /// Asserts that `got` agrees with the fixture's `key` within
    /// [`TOLERANCE_PX`], printing the largest difference.
    pub fn assert_matches(fixture: &StateDict, key: &str, got: Tensor<4>, name: &str) {
        let want = &fixture.tensors[key].values;
        let got = values(got);
        assert_eq!(got.len(), want.len(), "{name} {key}: sizes differ");
        let worst = got
            .iter()
            .zip(want)
            .map(|(g, w)| (g - w).abs())
            .fold(0.0f32, f32::max);
        println!("{name}: {key}: largest difference {worst:.2e} px");
        assert!(worst <= TOLERANCE_PX, "{name} {key}: {worst} px");
    }
}
