//! The overhead camera path: frames rendered by `camera::render_frame` and views cut from them by
//! `camera::cut_view`, measured against the crops `view::render_crop` draws directly (what Psi
//! was trained on). The effect on Psi's F is measured in grop-onboard's `cut_vs_render` test.

use world::camera::{
    CameraError, FrameLayout, OverheadCamera, PixelFormat, cut_view, render_frame, rgb_to_gray,
};
use world::view::{CROP_CELLS, FLOOR_GRAY, Side, TABLE_GRAY, render_crop};

/// Mean absolute difference per pixel (gray levels) between cut and rendered crops.
fn mean_abs_diff(a: &[u8; CROP_CELLS], b: &[u8; CROP_CELLS]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| f64::from(x.abs_diff(*y)))
        .sum::<f64>()
        / CROP_CELLS as f64
}

/// Every (target, side) of 30 generated scenes (10 training, 20 evaluation with 15..25 chairs):
/// crops cut from the default 640 x 480 frame and from a coarser (8 cm/px) and a finer frame
/// differ from the rendered crops only at outlines.
#[test]
fn cut_crops_match_rendered_crops() {
    let mut scenes = world::generate::training_scenes(11, 10, 3);
    scenes.extend(
        world::generate::evaluation_suite(12, 3)
            .into_iter()
            .step_by(3),
    );
    scenes.extend((0..10).map(|i| world::generate::evaluation_scene(100 + i, 25, 3)));
    for (size, limit_mean, limit_worst) in [
        ((640, 480), 1.5, 4.0),
        ((1280, 960), 1.0, 3.0),
        ((250, 153), 4.0, 9.0),
    ] {
        let (mut total, mut worst, mut count, mut max_px) = (0.0, 0.0f64, 0usize, 0u8);
        for scene in &scenes {
            let camera = OverheadCamera::fitting_room_with(scene, size.0, size.1);
            let mut frame = vec![0u8; camera.rgb8_len()];
            render_frame(scene, &camera, &mut frame).unwrap();
            let layout = FrameLayout::rgb8(camera);
            for target in &scene.targets {
                for side in Side::BOTH {
                    let mut cut = [0u8; CROP_CELLS];
                    cut_view(&frame, &layout, target.x_m, side, &mut cut).unwrap();
                    let rendered = render_crop(scene, target.x_m, side);
                    let d = mean_abs_diff(&cut, &rendered);
                    total += d;
                    worst = worst.max(d);
                    count += 1;
                    let px = cut.iter().zip(&rendered).map(|(a, b)| a.abs_diff(*b)).max();
                    max_px = max_px.max(px.unwrap_or(0));
                }
            }
        }
        let mean = total / count as f64;
        println!(
            "{}x{} px: {count} crops, mean |cut - rendered| = {mean:.3} gray levels/px, worst crop {worst:.3}, worst pixel {max_px}",
            size.0, size.1
        );
        assert!(mean < limit_mean, "{size:?}: mean {mean}");
        assert!(worst < limit_worst, "{size:?}: worst crop {worst}");
    }
}

/// Flat areas convert exactly: an empty room's crop cut from the frame is identical to the
/// rendered one, floor and table levels away from the table's outline.
#[test]
fn flat_areas_are_exact() {
    let mut scene = world::Scene::empty_paper_room();
    scene.targets = vec![world::UnloadTarget::on_center_line(0.3)];
    let camera = OverheadCamera::fitting_room(&scene);
    let mut frame = vec![0u8; camera.rgb8_len()];
    render_frame(&scene, &camera, &mut frame).unwrap();
    let layout = FrameLayout::rgb8(camera);
    let mut cut = [0u8; CROP_CELLS];
    cut_view(&frame, &layout, 0.3, Side::Near, &mut cut).unwrap();
    let rendered = render_crop(&scene, 0.3, Side::Near);
    assert_eq!(cut, rendered);
    // Away from the table's edge row (y = 5.8 m lies inside crop row 3) only the two levels.
    for (i, &g) in cut.iter().enumerate() {
        if i / 64 != 3 {
            assert!(g == FLOOR_GRAY || g == TABLE_GRAY, "cell {i}: {g}");
        }
    }
    // Pixel (0, 0) is outside the room (black), the room's centre is floor.
    assert_eq!(rgb_to_gray([frame[0], frame[1], frame[2]]), 0);
}

/// The same frame as Mono8 with padded rows gives the same crops as RGB8.
#[test]
fn mono8_with_row_padding_cuts_the_same() {
    let scene = world::generate::evaluation_scene(5, 20, 3);
    let camera = OverheadCamera::fitting_room(&scene);
    let mut rgb = vec![0u8; camera.rgb8_len()];
    render_frame(&scene, &camera, &mut rgb).unwrap();
    let stride = camera.width_px as usize + 13;
    let mut mono = vec![0u8; stride * camera.height_px as usize];
    for (row, line) in rgb.chunks_exact(camera.width_px as usize * 3).enumerate() {
        for (col, px) in line.chunks_exact(3).enumerate() {
            mono[row * stride + col] = rgb_to_gray([px[0], px[1], px[2]]);
        }
    }
    let mono_layout = FrameLayout {
        camera,
        format: PixelFormat::Mono8,
        row_stride_bytes: stride,
    };
    for target in &scene.targets {
        for side in Side::BOTH {
            let (mut a, mut b) = ([0u8; CROP_CELLS], [0u8; CROP_CELLS]);
            cut_view(&rgb, &FrameLayout::rgb8(camera), target.x_m, side, &mut a).unwrap();
            cut_view(&mono, &mono_layout, target.x_m, side, &mut b).unwrap();
            // Mono8 rounds each pixel's gray once more: at most one level apart.
            assert!(a.iter().zip(&b).all(|(x, y)| x.abs_diff(*y) <= 1));
        }
    }
}

#[test]
fn bad_headers_and_views_outside_the_frame_are_errors() {
    let scene = world::generate::evaluation_scene(5, 20, 3);
    let camera = OverheadCamera::fitting_room(&scene);
    let frame = vec![0u8; camera.rgb8_len()];
    let layout = FrameLayout::rgb8(camera);
    let mut crop = [0u8; CROP_CELLS];
    assert!(matches!(
        cut_view(&frame, &layout, 9.0, Side::Near, &mut crop),
        Err(CameraError::ViewOutsideFrame { .. })
    ));
    assert!(matches!(
        cut_view(&frame, &layout, f64::NAN, Side::Near, &mut crop),
        Err(CameraError::BadTarget(_))
    ));
    assert!(matches!(
        cut_view(&frame[1..], &layout, 0.0, Side::Near, &mut crop),
        Err(CameraError::BufferTooSmall { .. })
    ));
    let mut short = layout;
    short.row_stride_bytes -= 1;
    assert!(cut_view(&frame, &short, 0.0, Side::Near, &mut crop).is_err());
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let mut l = layout;
        l.camera.metres_per_px = bad;
        assert!(cut_view(&frame, &l, 0.0, Side::Far, &mut crop).is_err());
    }
    let mut empty = layout;
    empty.camera.height_px = 0;
    assert!(cut_view(&frame, &empty, 0.0, Side::Far, &mut crop).is_err());
    let mut small = vec![0u8; 10];
    assert!(render_frame(&scene, &camera, &mut small).is_err());
    // A frame that sees only part of the room: the view over a target outside it is an error.
    let mut corner = camera;
    corner.width_px = 100;
    let corner_frame = vec![0u8; corner.rgb8_len()];
    assert!(
        cut_view(
            &corner_frame,
            &FrameLayout::rgb8(corner),
            0.0,
            Side::Near,
            &mut crop
        )
        .is_err()
    );
}
