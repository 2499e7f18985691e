//! Seeded mutations of a valid manifest (with its files on disk): loading
//! never panics and its errors name the manifest; `validate --deep` never
//! panics either.

use mbs_dataset::Manifest;
use mbs_dataset::validate::{ValidateOptions, validate_manifest};
use mbs_test_support::mutation::fuzz_reader;

#[test]
fn mutated_manifests_never_panic_and_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["a0.png", "a1.png"] {
        image::RgbImage::new(4, 3)
            .save(dir.path().join(name))
            .unwrap();
    }
    let map = mbs_core::FloatImage::new(4, 3);
    mbs_core::formats::pfm::write_pfm_grey(
        &dir.path().join("d.pfm"),
        &map,
        mbs_core::formats::pfm::Endian::Little,
    )
    .unwrap();
    let valid = serde_json::json!({
        "format": "mbs-manifest/1",
        "name": "fuzz",
        "rig": {"num_views": 2, "baseline_m": 0.5, "focal_px": 480.0, "cx": 1.5, "cy": 1.0, "width": 4, "height": 3},
        "samples": [{"id": "Town01/ClearNoon/000001", "split": "train", "views": ["a0.png", "a1.png"],
                     "ground_truth": [{"reference": 0, "target": 1, "disparity": "d.pfm", "scale": 2.0}],
                     "image_size": [4, 3]}]
    })
    .to_string();
    Manifest::load(&{
        let path = dir.path().join("valid.json");
        std::fs::write(&path, &valid).unwrap();
        path
    })
    .unwrap();
    let summary = fuzz_reader(valid.as_bytes(), dir.path(), "json", (1500, 11), |path| {
        validate_manifest(path, ValidateOptions { deep: true }, &());
        Manifest::load(path).map(drop)
    })
    .unwrap();
    assert_eq!(summary.failures, Vec::<String>::new());
    assert!(summary.refused > summary.cases / 2, "{summary:?}");
}
