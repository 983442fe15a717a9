//! View and crop geometry and rendering.

use proptest::prelude::*;
use world::scene::{Chair, Scene};
use world::view::{
    self, CANDIDATE_COLS, CANDIDATE_ROWS, CHAIR_GRAY, CROP_COLS, CROP_ROWS, FLOOR_GRAY, Side,
    TABLE_GRAY, cell_center_world, render_crop, world_to_cell,
};

#[test]
fn near_cell_centres_follow_the_convention() {
    let (x, y) = cell_center_world(1.0, Side::Near, 0, 0);
    assert!((x - (1.0 - 2.0 + 0.03125)).abs() < 1e-12);
    assert!((y - (6.0 - 0.03125)).abs() < 1e-12);
    // The candidate band: 1.5 m along the table centred on the target, 0.5625 .. 1.0625 m off.
    let (x0, y0) = cell_center_world(
        0.0,
        Side::Near,
        *CANDIDATE_ROWS.start(),
        *CANDIDATE_COLS.start(),
    );
    let (x1, y1) = cell_center_world(
        0.0,
        Side::Near,
        *CANDIDATE_ROWS.end(),
        *CANDIDATE_COLS.end(),
    );
    assert!(((x1 - x0) - 23.0 * 0.0625).abs() < 1e-12 && (x0 + x1).abs() < 1e-12);
    assert!(((6.0 - y0) - (0.5625 + 0.03125)).abs() < 1e-12);
    assert!(((6.0 - y1) - (1.0625 - 0.03125)).abs() < 1e-12);
}

proptest! {
    #[test]
    fn far_cell_is_point_mirror_of_near_cell(tx in -6.0f64..6.0, row in 0usize..32, col in 0usize..64) {
        let (nx, ny) = cell_center_world(tx, Side::Near, row, col);
        let (fx, fy) = cell_center_world(tx, Side::Far, row, col);
        prop_assert!((nx + fx - 2.0 * tx).abs() < 1e-9);
        prop_assert!((ny + fy - 12.0).abs() < 1e-9);
    }

    #[test]
    fn world_to_cell_inverts_cell_center(tx in -6.0f64..6.0, row in 0usize..32, col in 0usize..64, far in any::<bool>()) {
        let side = if far { Side::Far } else { Side::Near };
        let (x, y) = cell_center_world(tx, side, row, col);
        prop_assert_eq!(world_to_cell(tx, side, x, y), Some((row, col)));
    }
}

#[test]
fn points_outside_the_crop_have_no_cell() {
    assert_eq!(
        world_to_cell(0.0, Side::Near, 0.0, 6.1),
        None,
        "far half is not in the near crop"
    );
    assert_eq!(world_to_cell(0.0, Side::Near, 2.1, 5.0), None);
    assert_eq!(world_to_cell(0.0, Side::Far, 0.0, 5.9), None);
    assert_eq!(world_to_cell(0.0, Side::Near, f64::NAN, 5.0), None);
}

#[test]
fn empty_room_crop_shows_table_then_floor() {
    let scene = Scene::empty_paper_room();
    for side in Side::BOTH {
        let crop = render_crop(&scene, 0.0, side);
        // The table's half-depth is 0.2 m = 3.2 cells: rows 0..=2 table, row 3 mixed, rest floor.
        for col in 0..CROP_COLS {
            for row in 0..3 {
                assert_eq!(crop[row * CROP_COLS + col], TABLE_GRAY);
            }
            let mixed = crop[3 * CROP_COLS + col];
            assert!(
                mixed > FLOOR_GRAY && mixed < TABLE_GRAY,
                "row 3 is partly table: {mixed}"
            );
            for row in 4..CROP_ROWS {
                assert_eq!(crop[row * CROP_COLS + col], FLOOR_GRAY);
            }
        }
    }
}

#[test]
fn chair_appears_where_it_stands_and_only_on_its_side() {
    let mut scene = Scene::empty_paper_room();
    scene.chairs.push(Chair::new(1.0, 5.0, 0.3));
    let target_x = 0.5;
    let near = render_crop(&scene, target_x, Side::Near);
    let (row, col) =
        world_to_cell(target_x, Side::Near, 1.0, 5.0).expect("chair centre is in the near crop");
    assert_eq!(near[row * CROP_COLS + col], CHAIR_GRAY);
    let far = render_crop(&scene, target_x, Side::Far);
    assert!(!far.contains(&CHAIR_GRAY));

    // The same chair mirrored through the target shows up at the same cell of the far crop.
    let mut mirrored = Scene::empty_paper_room();
    mirrored.chairs.push(Chair::new(
        2.0 * target_x - 1.0,
        12.0 - 5.0,
        0.3 + std::f64::consts::PI,
    ));
    let far = render_crop(&mirrored, target_x, Side::Far);
    assert_eq!(
        far, near,
        "far crop of the mirrored scene equals the near crop"
    );
}

#[test]
fn crop_at_the_table_end_sees_the_floor_past_it() {
    let scene = Scene::empty_paper_room();
    // Target 0.25 m from the east end (6.75): the table ends 2.25 m before the crop's east edge.
    let crop = render_crop(&scene, 6.5, Side::Near);
    assert_eq!(crop[0], TABLE_GRAY);
    assert_eq!(crop[CROP_COLS - 1], FLOOR_GRAY);
}

#[test]
fn rendering_is_deterministic_and_full_view_matches_crops() {
    let scene = world::generate::training_scenes(3, 1, 1).remove(0);
    let tx = scene.targets[0].x_m;
    assert_eq!(
        render_crop(&scene, tx, Side::Near),
        render_crop(&scene, tx, Side::Near)
    );
    let full = view::render_view(&scene, tx);
    let near = render_crop(&scene, tx, Side::Near);
    assert_eq!(&full[32 * 64..], &near[..]);
}

#[test]
fn room_picture_has_the_room_size() {
    let scene = world::generate::evaluation_scene(1, 15, 3);
    let rv = view::RoomView::whole_room(&scene, 20.0);
    let img = view::render_room(&scene, &rv);
    assert_eq!((img.width(), img.height()), (400, 244));
    // A chair's centre pixel has the chair colour (blue dominant).
    let c = scene.chairs[0];
    let (px, py) = rv.to_pixel(c.x_m, c.y_m);
    let p = img.get_pixel(px as u32, py as u32);
    assert!(p.0[2] > p.0[0], "{p:?}");
}
