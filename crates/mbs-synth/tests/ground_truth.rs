//! Ground-truth checks of rendered scenes: determinism, exact depth of
//! hand-placed geometry, occlusion masks, and the acceptance test that the
//! exact disparity warps every view back onto camera 0.

use mbs_core::formats::carla;
use mbs_core::{FloatImage, MaskImage, RgbImage, Rig, Side};
use mbs_image::quality::psnr;
use mbs_image::resample::warp_from_target;
use mbs_synth::{
    Material, Object, Pattern, RenderOptions, Scene, SceneConfig, Shape, Weather, occlusion_mask,
    one_step_disparity, render,
};

/// A small rig shaped like MBS20K's (same field of view), 4 cameras.
fn small_rig() -> Rig {
    Rig::centred(4, 0.5, 80.0, 160, 96)
}

fn grey() -> Material {
    Material {
        pattern: Pattern::Plain,
        base: [0.5, 0.5, 0.5],
        accent: [0.4, 0.4, 0.4],
        detail_period_m: 1.0,
        seed: 1,
    }
}

fn cuboid(min: [f64; 3], max: [f64; 3]) -> Object {
    Object {
        shape: Shape::Cuboid { min, max },
        material: grey(),
    }
}

#[test]
fn same_seed_same_images_other_seed_other_images() {
    let rig = small_rig();
    let config = SceneConfig::centred_on(&rig);
    let options = RenderOptions::default();
    let a = render(&Scene::generate(11, &config), &rig, &options);
    let b = render(&Scene::generate(11, &config), &rig, &options);
    let c = render(&Scene::generate(12, &config), &rig, &options);
    assert_eq!(a.views, b.views);
    assert_eq!(a.depth, b.depth);
    assert_ne!(a.views[0], c.views[0]);
    assert_ne!(a.depth[0], c.depth[0]);
}

#[test]
fn empty_scene_is_sky_at_the_far_plane() {
    let rig = small_rig();
    let out = render(
        &Scene::new(None, Vec::new(), 0),
        &rig,
        &RenderOptions::default(),
    );
    for depth in &out.depth {
        assert!(depth.as_raw().iter().all(|&z| z == 1000.0));
    }
    // The CARLA encoding of the sky decodes to its far plane.
    assert_eq!(
        carla::decode_code(carla::code(carla::encode_value(1000.0))),
        1000.0
    );
    // A generated street shows sky somewhere, at exactly 1000 m.
    let street = render(
        &Scene::generate(3, &SceneConfig::centred_on(&rig)),
        &rig,
        &RenderOptions::default(),
    );
    assert!(street.depth[0].as_raw().contains(&1000.0));
    assert!(
        street.depth[0]
            .as_raw()
            .iter()
            .all(|&z| z > 0.0 && z <= 1000.0)
    );
}

#[test]
fn depth_of_hand_placed_planes_is_analytic() {
    let rig = small_rig();
    // A wall whose front face is the plane z = 12 m, covering every view.
    let wall = Scene::new(
        None,
        vec![cuboid([-100.0, -100.0, 12.0], [100.0, 100.0, 13.0])],
        0,
    );
    let out = render(&wall, &rig, &RenderOptions::default());
    for depth in &out.depth {
        assert!(depth.as_raw().iter().all(|&z| z == 12.0));
    }
    // The ground 1.6 m below the cameras: z = f * h / (v - cy) below the
    // horizon, sky above it (or where the ground lies beyond the far plane).
    let config = SceneConfig {
        camera_height_m: 1.6,
        side_buildings: false,
        back_buildings: false,
        boxes: 0,
        poles: 0,
        ..SceneConfig::centred_on(&rig)
    };
    let ground = render(
        &Scene::generate(0, &config),
        &rig,
        &RenderOptions::default(),
    );
    for k in 0..rig.num_views {
        for (x, y, z) in ground.depth[k].enumerate_pixels() {
            let dv = f64::from(y) - rig.cy;
            let expected = if dv > 0.0 {
                (rig.focal_px * 1.6 / dv).min(1000.0)
            } else {
                1000.0
            };
            let z = f64::from(z.0[0]);
            assert!(
                (z - expected).abs() <= 1e-6 * expected,
                "({x}, {y}) camera {k}: {z} vs {expected}"
            );
        }
    }
    // The one-step disparity is f * B / z.
    let d = one_step_disparity(&out.depth[0], &rig);
    assert!(
        d.as_raw()
            .iter()
            .all(|&v| (f64::from(v) - 80.0 * 0.5 / 12.0).abs() < 1e-5)
    );
}

#[test]
fn object_in_front_of_a_wall_occludes_a_strip() {
    // f = 100 px, B = 0.5 m: the wall at 20 m moves 2.5 px between the
    // cameras, the box face at 5 m moves 10 px.
    let rig = Rig::centred(2, 0.5, 100.0, 128, 64);
    let scene = Scene::new(
        None,
        vec![
            cuboid([-50.0, -50.0, 20.0], [50.0, 50.0, 21.0]),
            cuboid([0.01, -1.0, 5.0], [0.51, 1.0, 6.0]),
        ],
        0,
    );
    let column = |x_m: f64, z_m: f64, camera_x: f64| rig.focal_px * (x_m - camera_x) / z_m + rig.cx;
    // In camera 0 the box spans columns 63.7..73.7, rows 11.5..51.5.
    let (left, right) = (column(0.01, 5.0, 0.0), column(0.51, 5.0, 0.0));
    // A wall point at column u shows at u - 2.5 in camera 1, where the box
    // spans left - 10 .. right - 10: hidden for u in [left - 7.5, left).
    let mask = occlusion_mask(&scene, &rig, 0, 1);
    let row = 31;
    for x in 0..rig.width {
        let u = f64::from(x);
        let behind_box = u >= left - 7.5 && u < left;
        let off_frame = u - 2.5 < 0.0;
        let expected = if behind_box || off_frame { 255 } else { 0 };
        assert_eq!(
            mask.get_pixel(x, row).0[0],
            expected,
            "column {x} (box {left}..{right})"
        );
    }
    assert_eq!(
        (0..rig.width)
            .filter(|&x| mask.get_pixel(x, row).0[0] == 255)
            .count(),
        3 + 7,
        "three frame-edge columns and seven hidden wall columns"
    );
    // Above the box only the frame-edge strip is left.
    assert!((0..rig.width).all(|x| (mask.get_pixel(x, 2).0[0] == 255) == (x < 3)));
    // Seen from camera 1 with camera 0 as target, the strip is at the right
    // edge and the hidden wall is right of the box.
    let back = occlusion_mask(&scene, &rig, 1, 0);
    let left1 = column(0.01, 5.0, 0.5);
    let right1 = column(0.51, 5.0, 0.5);
    for x in 0..rig.width {
        let u = f64::from(x);
        let behind_box = u > right1 && u <= right1 + 7.5;
        let off_frame = u + 2.5 > f64::from(rig.width - 1);
        let expected = if behind_box || off_frame { 255 } else { 0 };
        assert_eq!(
            back.get_pixel(x, row).0[0],
            expected,
            "column {x} (box {left1}..{right1})"
        );
    }
}

/// Texture statistics over horizontal neighbour pairs on the same surface
/// (depth within 2 %, not sky), so depth edges do not count: the mean
/// absolute difference over all channels, and the share of pairs whose
/// channel-summed difference is at least 3 (texture nearly everywhere, not
/// only at pattern edges).
fn texture_gradient(view: &RgbImage, depth: &FloatImage) -> (f64, f64) {
    let mut sum = 0.0;
    let mut textured = 0usize;
    let mut pairs = 0usize;
    for y in 0..view.height() {
        for x in 1..view.width() {
            let (z0, z1) = (depth.get_pixel(x - 1, y).0[0], depth.get_pixel(x, y).0[0]);
            if z0 >= 1000.0 || z1 >= 1000.0 || (z0 - z1).abs() > 0.02 * z0 {
                continue;
            }
            let (a, b) = (view.get_pixel(x - 1, y).0, view.get_pixel(x, y).0);
            let diff: f64 = (0..3)
                .map(|c| (f64::from(a[c]) - f64::from(b[c])).abs())
                .sum();
            sum += diff;
            textured += usize::from(diff >= 3.0);
            pairs += 1;
        }
    }
    let pairs = pairs.max(1) as f64;
    (sum / (3.0 * pairs), textured as f64 / pairs)
}

/// PSNR (dB) of camera 0 rebuilt from camera `k` with the exact disparity,
/// over pixels valid for the warp and not occluded in camera `k`.
fn warp_psnr(scene: &Scene, rig: &Rig, views: &[RgbImage], one_step: &FloatImage, k: usize) -> f64 {
    let disparity = FloatImage::from_fn(rig.width, rig.height, |x, y| {
        image::Luma([one_step.get_pixel(x, y).0[0] * k as f32])
    });
    let (warped, valid) = warp_from_target(&views[k], &disparity, Side::Right);
    let occluded = occlusion_mask(scene, rig, 0, k);
    let mask = MaskImage::from_fn(rig.width, rig.height, |x, y| {
        let keep = valid.get_pixel(x, y).0[0] != 0 && occluded.get_pixel(x, y).0[0] == 0;
        image::Luma([if keep { 255 } else { 0 }])
    });
    let counted = mask.as_raw().iter().filter(|&&m| m != 0).count();
    assert!(
        counted > mask.as_raw().len() / 2,
        "too few pixels compared: {counted}"
    );
    psnr(&warped, &views[0], Some(&mask)).expect("the mask keeps pixels and sizes match")
}

#[test]
fn exact_disparity_warps_every_view_onto_camera_0() {
    let rig = small_rig();
    for seed in [0, 1] {
        let scene = Scene::generate(seed, &SceneConfig::centred_on(&rig));
        let start = std::time::Instant::now();
        let out = render(&scene, &rig, &RenderOptions::default());
        println!("seed {seed}: rendered 4 x 160x96 in {:?}", start.elapsed());
        let one_step = one_step_disparity(&out.depth[0], &rig);
        for k in 1..rig.num_views {
            let db = warp_psnr(&scene, &rig, &out.views, &one_step, k);
            println!("seed {seed}: camera {k} -> 0: PSNR {db:.2} dB");
            assert!(
                db >= 30.0,
                "seed {seed}, camera {k}: PSNR {db:.2} dB < 30 dB"
            );
        }
    }
}

#[test]
fn every_weather_is_textured_and_warps_well() {
    let rig = small_rig();
    let scene = Scene::generate(5, &SceneConfig::centred_on(&rig));
    for weather in Weather::ALL {
        let out = render(
            &scene,
            &rig,
            &RenderOptions {
                weather,
                ..RenderOptions::default()
            },
        );
        let (gradient, textured) = texture_gradient(&out.views[0], &out.depth[0]);
        let one_step = one_step_disparity(&out.depth[0], &rig);
        let db = warp_psnr(&scene, &rig, &out.views, &one_step, 3);
        println!(
            "{weather}: texture gradient {gradient:.2}, textured pairs {:.0} %, camera 3 -> 0: PSNR {db:.2} dB",
            100.0 * textured
        );
        assert!(db >= 30.0, "{weather}: PSNR {db:.2} dB");
        // Flat shading (patterns only, no noise) measures about 2.8 / 30 %
        // at noon and 2.2 / 21 % at night on this scene.
        let (min_gradient, min_textured) = match weather {
            Weather::ClearNoon => (4.5, 0.6),
            Weather::ClearNight => (2.0, 0.4),
            _ => (2.0, 0.6),
        };
        assert!(
            gradient > min_gradient,
            "{weather}: texture gradient {gradient:.2}"
        );
        assert!(
            textured > min_textured,
            "{weather}: textured pairs {textured:.2}"
        );
    }
}
