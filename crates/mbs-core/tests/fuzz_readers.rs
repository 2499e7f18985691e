//! Seeded mutation tests of every file reader in mbs-core: valid files of
//! each format (PFM grey and colour, PNG 8-bit RGB, grey and 16-bit, PNM,
//! EXR, CARLA depth) get bit flips, truncations, inserted bytes and absurd
//! header numbers; every reader must return (never panic), and every error
//! must name the file. The same seed gives the same cases everywhere.

#![allow(clippy::unwrap_used)] // test code: a panic is the failure report

use std::path::Path;

use mbs_core::formats::{carla, exr, pfm, png16, read_disparity, rgb};
use mbs_core::{FloatImage, Result};
use mbs_test_support::mutation::fuzz_reader;

/// Mutated files per valid file.
const CASES_PER_FORMAT: usize = 1000;

type Reader = fn(&Path) -> Result<()>;

/// A valid file of each format and the reader that reads it back: its
/// extension, its bytes and the reader. The order is part of the cases'
/// seeds (each file's index is its seed).
fn valid_files(dir: &Path) -> Vec<(&'static str, Vec<u8>, Reader)> {
    let map = FloatImage::from_fn(9, 7, |x, y| image::Luma([x as f32 * 1.5 + y as f32]));
    let mut files = float_files(dir, &map);
    files.extend(png_files(dir, &map));
    files.extend(pnm_files(dir));
    files
}

/// The bytes of the file `name` in `dir` that `write` writes.
fn written(dir: &Path, name: &str, write: &dyn Fn(&Path)) -> Vec<u8> {
    let path = dir.join(name);
    write(&path);
    std::fs::read(&path).unwrap()
}

/// An 8-bit colour image of 9 x 7 pixels.
fn colour_image() -> image::RgbImage {
    image::RgbImage::from_fn(9, 7, |x, y| image::Rgb([x as u8 * 20, y as u8 * 30, 7]))
}

/// An 8-bit grey image of 9 x 7 pixels.
fn grey_image() -> image::GrayImage {
    image::GrayImage::from_fn(9, 7, |x, y| image::Luma([(x * y) as u8]))
}

/// PFM (grey little-endian, colour big-endian) and EXR files of `map`.
fn float_files(dir: &Path, map: &FloatImage) -> Vec<(&'static str, Vec<u8>, Reader)> {
    vec![
        (
            "pfm",
            written(dir, "v.pfm", &|p| {
                pfm::write_pfm_grey(p, map, pfm::Endian::Little).unwrap()
            }),
            |p| pfm::read_pfm(p).map(drop),
        ),
        (
            "pfm",
            written(dir, "c.pfm", &|p| {
                let rgb = image::Rgb32FImage::from_fn(5, 4, |x, _| image::Rgb([x as f32; 3]));
                pfm::write_pfm_rgb(p, &rgb, pfm::Endian::Big).unwrap()
            }),
            |p| read_disparity(p, None).map(drop),
        ),
        (
            "exr",
            written(dir, "v.exr", &|p| exr::write_exr(p, map).unwrap()),
            |p| exr::read_exr(p).map(drop),
        ),
    ]
}

/// PNG files: 8-bit colour, CARLA depth, a mask, KITTI disparity and
/// 16-bit depth in millimetres.
fn png_files(dir: &Path, map: &FloatImage) -> Vec<(&'static str, Vec<u8>, Reader)> {
    vec![
        (
            "png",
            written(dir, "v.png", &|p| {
                rgb::write_rgb_png(p, &colour_image()).unwrap()
            }),
            |p| rgb::read_rgb(p).map(drop),
        ),
        (
            "png",
            written(dir, "d.png", &|p| {
                let depth = FloatImage::from_fn(9, 7, |x, _| image::Luma([5.0 + x as f32]));
                rgb::write_rgb_png(p, &carla::encode_depth(&depth)).unwrap()
            }),
            |p| rgb::read_rgb8_strict(p).map(|encoded| drop(carla::decode_depth(&encoded))),
        ),
        (
            "png",
            written(dir, "m.png", &|p| {
                rgb::write_mask_png(p, &grey_image()).unwrap()
            }),
            |p| rgb::read_mask(p).map(drop),
        ),
        (
            "png",
            written(dir, "k.png", &|p| {
                png16::write_kitti_disparity(p, map).unwrap()
            }),
            |p| read_disparity(p, None).map(drop),
        ),
        (
            "png",
            written(dir, "z.png", &|p| png16::write_depth_mm(p, map).unwrap()),
            |p| png16::read_depth_mm(p).map(drop),
        ),
    ]
}

/// PPM (colour) and PGM (grey) files.
fn pnm_files(dir: &Path) -> Vec<(&'static str, Vec<u8>, Reader)> {
    vec![
        (
            "ppm",
            written(dir, "v.ppm", &|p| colour_image().save(p).unwrap()),
            |p| rgb::read_rgb(p).map(drop),
        ),
        (
            "pgm",
            written(dir, "g.pgm", &|p| grey_image().save(p).unwrap()),
            |p| read_disparity(p, Some(4.0)).map(drop),
        ),
    ]
}

#[test]
fn mutated_files_never_panic_and_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (mut cases, mut refused) = (0, 0);
    for (seed, (ext, valid, read)) in valid_files(dir.path()).into_iter().enumerate() {
        let summary = fuzz_reader(
            &valid,
            dir.path(),
            ext,
            (CASES_PER_FORMAT, seed as u64),
            read,
        )
        .unwrap();
        assert_eq!(
            summary.failures,
            Vec::<String>::new(),
            "format {seed} ({ext})"
        );
        cases += summary.cases;
        refused += summary.refused;
    }
    // Most mutations break a file; a reader that accepted everything would
    // not be reading.
    assert!(
        refused > cases / 3,
        "only {refused} of {cases} mutated files refused"
    );
}
