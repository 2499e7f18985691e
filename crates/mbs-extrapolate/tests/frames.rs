//! A frame on disk through the library: Tsukuba's (col3, col4) extrapolated
//! with the built-in matcher, every output written, and the 4-view
//! manifest of it; a frame without any disparity source is refused.

use std::path::{Path, PathBuf};

use mbs_dataset::pairs::PairSource;
use mbs_extrapolate::{DisparitySource, Extrapolator, four_view_manifest, pair_frame};
use mbs_infer::inpaint::BackgroundFill;
use mbs_warp::Dilation;

fn view(col: u32) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/middlebury-tsukuba-row3")
        .join(format!("scene1.row3.col{col}.ppm"))
}

#[test]
fn a_frame_is_written_whole_and_described_by_its_manifest() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let pair = PairSource::Single {
        left: view(3),
        right: view(4),
    }
    .pairs()
    .unwrap()
    .remove(0);
    let frame = pair_frame(&pair, &out, (None, None), None).unwrap();
    let extrapolator = Extrapolator::new(Dilation::None, Box::new(BackgroundFill::default()));

    let err = frame.process(&extrapolator, None, false).unwrap_err();
    assert!(err.to_string().contains("col3.ppm: no disparity"), "{err}");
    assert!(!frame.is_done(false));
    assert!(!out.exists());

    let source = DisparitySource::builtin(16);
    frame.process(&extrapolator, Some(&source), true).unwrap();
    assert!(frame.is_done(true));
    let image_1 = mbs_core::formats::rgb::read_rgb(&frame.image_1).unwrap();
    let real = mbs_core::formats::rgb::read_rgb(&view(2)).unwrap();
    let psnr = mbs_image::quality::psnr(&image_1, &real, None).unwrap();
    assert!(psnr > 28.7, "{psnr}"); // measured 28.89 dB

    let manifest = four_view_manifest(&[frame.files()], &out, 615.0, 0.16).unwrap();
    let sample = &manifest.samples[0];
    assert_eq!(manifest.rig.num_views, 4);
    assert_eq!(sample.views[0], "image_1.png");
    assert_eq!(sample.synthesized_masks[3].as_deref(), Some("mask_4.png"));
    // The inputs are linked into the output folder, which stands alone.
    assert_eq!(sample.views[1], "image_2.ppm");
    assert_eq!(
        std::fs::read(out.join("image_3.ppm")).unwrap(),
        std::fs::read(view(4)).unwrap()
    );
}
