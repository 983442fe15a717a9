//! `plan_place` and IK allocate nothing: a counting global allocator around the calls.

use core::f64::consts::FRAC_PI_2;
use planar::Pose2;

use nalgebra::{Point3, Vector3};
use ur5e_kin::{ObstacleBox, PlaceConfig, Ur5e, arm_collides, plan_place};

#[global_allocator]
static GLOBAL: test_support::CountingAlloc = test_support::CountingAlloc;

#[test]
fn placement_and_ik_do_not_allocate() {
    let cfg = PlaceConfig::default();
    let arm = Ur5e::default();
    let obstacles = vec![
        ObstacleBox::from_min_max(Point3::new(-1.5, 5.8, 0.0), Point3::new(1.5, 6.2, 1.0)),
        ObstacleBox {
            center: Point3::new(0.5, 5.0, 0.45),
            half_extents: Vector3::new(0.225, 0.225, 0.45),
            yaw_rad: 0.3,
        },
    ];
    let goal = Point3::new(0.0, 6.0, 1.3);
    let poses: Vec<Pose2> = [0.5, 0.7, 0.9, 1.1, 1.3]
        .iter()
        .map(|off| Pose2 {
            x_m: 0.1,
            y_m: 6.0 - off,
            yaw_rad: FRAC_PI_2,
        })
        .collect();
    let q = [0.4, -1.2, 1.1, -1.3, 1.0, 0.6];
    let flange = arm.forward(&q);

    test_support::count_this_thread(true);
    let before = test_support::this_thread_allocations();
    let mut outcomes = 0usize;
    for base in &poses {
        outcomes += plan_place(&cfg, *base, goal, &obstacles).is_ok() as usize;
        outcomes += arm_collides(&cfg, *base, &q, &obstacles) as usize;
    }
    outcomes += arm.inverse(&flange).len();
    let after = test_support::this_thread_allocations();
    test_support::count_this_thread(false);
    assert_eq!(after - before, 0, "allocations in the placement path");
    assert!(outcomes > 0);
}
