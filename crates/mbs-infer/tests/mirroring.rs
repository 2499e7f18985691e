//! The right-view disparity through mirroring (conventions §2) on a constructed
//! pair: the right view is the left one shifted by a known disparity; and
//! the built-in matcher's search within a pair's own disparity bound.

use mbs_core::{RgbImage, Side};
use mbs_infer::{BlockMatcher, Disparity, Sgm, SgmConfig, StereoMatcher};

const SHIFT: u32 = 5;

/// A textured left view and its right view: `right(x) = left(x + SHIFT)`,
/// so a left pixel at `x` is seen at `x - SHIFT` in the right view.
fn shifted_pair() -> (RgbImage, RgbImage) {
    let (w, h) = (96, 48);
    let mut state = 0x2545_f491_u32;
    let mut texture = vec![0u8; ((w + SHIFT) * h) as usize];
    for v in &mut texture {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        *v = (state >> 24) as u8;
    }
    let at = |x: u32, y: u32| {
        let v = texture[(y * (w + SHIFT) + x) as usize];
        image::Rgb([v, v / 2, 255 - v])
    };
    let left = RgbImage::from_fn(w, h, at);
    let right = RgbImage::from_fn(w, h, |x, y| at(x + SHIFT, y));
    (left, right)
}

/// Share of the pixels in columns `cols` whose disparity is within 0.5 px
/// of `SHIFT`.
fn share_correct(d: &Disparity, cols: std::ops::Range<u32>) -> f64 {
    let mut hits = 0;
    let mut all = 0;
    for (x, _, v) in d.disparity.enumerate_pixels() {
        if cols.contains(&x) {
            all += 1;
            hits += usize::from((v.0[0] - SHIFT as f32).abs() <= 0.5);
        }
    }
    hits as f64 / all as f64
}

#[test]
fn right_view_disparity_comes_from_mirroring() {
    let (left, right) = shifted_pair();
    let sgm = Sgm::new(SgmConfig::with_max_disparity(16));
    let block = BlockMatcher {
        max_disparity: 16,
        window: 5,
    };
    for matcher in [&sgm as &dyn StereoMatcher, &block] {
        // Left view: columns past the shift see their match.
        let l = matcher.predict(&left, &right).expect("same size");
        // Right view: a right pixel at x is seen in the left view at x + 5,
        // so columns before width - shift see their match.
        let r = matcher.predict_right(&left, &right).expect("same size");
        let (share_l, share_r) = (share_correct(&l, 8..96), share_correct(&r, 0..88));
        println!("{}: left {share_l:.3}, right {share_r:.3}", matcher.name());
        assert!(share_l > 0.98 && share_r > 0.98, "{share_l} {share_r}");
    }
}

#[test]
fn mismatched_sizes_are_refused() {
    let (left, _) = shifted_pair();
    let small = RgbImage::new(10, 10);
    let err = Sgm::default().predict(&left, &small).unwrap_err();
    assert_eq!(
        err.to_string(),
        "the left view is (96, 48) (width, height) but the right view is (10, 10)"
    );
    assert!(Sgm::default().predict_right(&left, &small).is_err());
}

#[test]
fn a_pair_bound_replaces_the_search_range_of_the_built_in_matcher() {
    let (left, right) = shifted_pair();
    let sgm = Sgm::new(SgmConfig::with_max_disparity(64));
    for side in [Side::Right, Side::Left] {
        let (reference, target) = match side {
            Side::Right => (&left, &right),
            Side::Left => (&right, &left),
        };
        let within = sgm
            .predict_toward_within(reference, target, side, 16)
            .expect("same size");
        let sixteen = Sgm::new(SgmConfig::with_max_disparity(16))
            .predict_toward(reference, target, side)
            .expect("same size");
        assert_eq!(within, sixteen, "{side:?}");
        // A bound below the true disparity (5) cannot find it.
        let short = sgm
            .predict_toward_within(reference, target, side, 4)
            .expect("same size");
        let cols = if side == Side::Right { 8..96 } else { 0..88 };
        assert!(share_correct(&within, cols.clone()) > 0.98);
        assert!(share_correct(&short, cols) < 0.05);
    }
}
