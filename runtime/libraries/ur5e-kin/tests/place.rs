//! Placement: reach, tool-down tolerance, collision and failure classification.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use core::f64::consts::{FRAC_PI_2, PI};
use planar::Pose2;

use nalgebra::{Point3, Vector3};
use proptest::prelude::*;
use ur5e_kin::{ObstacleBox, PlaceConfig, PlaceFailure, arm_collides, plan_place};

/// The dinner-table world of docs/architecture.md around x = 0: table centre line y = 6,
/// 0.4 m deep, top at 1.0 m; the object goal 1.3 m high on the centre line.
fn table() -> ObstacleBox {
    ObstacleBox::from_min_max(Point3::new(-1.5, 5.8, 0.0), Point3::new(1.5, 6.2, 1.0))
}

fn goal() -> Point3<f64> {
    Point3::new(0.0, 6.0, 1.3)
}

/// The mobile base body as the world crate gives it: 0.60 x 0.55 m, up to the mount height.
fn base_body(cfg: &PlaceConfig, base: Pose2) -> ObstacleBox {
    ObstacleBox {
        center: Point3::new(base.x_m, base.y_m, 0.5 * cfg.mount.height_m),
        half_extents: Vector3::new(0.30, 0.275, 0.5 * cfg.mount.height_m),
        yaw_rad: base.yaw_rad,
    }
}

fn near_base(offset_m: f64) -> Pose2 {
    Pose2 {
        x_m: 0.0,
        y_m: 6.0 - offset_m,
        yaw_rad: FRAC_PI_2,
    }
}

/// Checks a plan: the object (TCP) is at the goal, the tool within the tolerance of down, the
/// joints within limits, and the arm clear of the obstacles.
fn assert_valid(cfg: &PlaceConfig, base: Pose2, goal: Point3<f64>, obstacles: &[ObstacleBox]) {
    let plan = plan_place(cfg, base, goal, obstacles).expect("placement");
    let tcp = plan
        .flange_world
        .transform_point(&Point3::new(0.0, 0.0, cfg.tcp_offset_m));
    assert!((tcp - goal).norm() < 1e-6, "object at {tcp}, goal {goal}");
    let axis = plan.flange_world.rotation * Vector3::z();
    let tilt = axis.angle(&-Vector3::z());
    assert!(
        tilt <= cfg.down_tolerance_rad + 1e-9,
        "tool tilted {tilt} rad"
    );
    assert!((tilt - plan.tool_tilt_rad).abs() < 1e-6);
    assert!(cfg.arm.limits.contains(&plan.joints));
    assert!(!arm_collides(cfg, base, &plan.joints, obstacles));
}

#[test]
fn default_config_validates_and_matches_design() {
    let cfg = PlaceConfig::default();
    cfg.validate().expect("default config is valid");
    assert!((1.0..=1.1).contains(&cfg.mount.height_m));
    assert!(cfg.mount.forward_m > 0.0);
}

#[test]
fn places_from_the_near_part_of_the_candidate_band() {
    let cfg = PlaceConfig::default();
    for offset in [0.56, 0.7, 0.8] {
        let base = near_base(offset);
        let obstacles = [table(), base_body(&cfg, base)];
        assert_valid(&cfg, base, goal(), &obstacles);
    }
}

#[test]
fn far_part_of_the_band_is_out_of_reach() {
    let cfg = PlaceConfig::default();
    let base = near_base(1.15);
    let obstacles = [table(), base_body(&cfg, base)];
    assert_eq!(
        plan_place(&cfg, base, goal(), &obstacles),
        Err(PlaceFailure::OutOfReach)
    );
    // Sideways along the table at the near row: reach is horizontal distance from the arm axis.
    let base = Pose2 {
        x_m: 0.9,
        ..near_base(0.56)
    }; // 0.97 m from the arm axis
    assert_eq!(
        plan_place(&cfg, base, goal(), &[]),
        Err(PlaceFailure::OutOfReach)
    );
}

#[test]
fn far_side_is_symmetric() {
    let cfg = PlaceConfig::default();
    let base = Pose2 {
        x_m: 0.2,
        y_m: 6.7,
        yaw_rad: -FRAC_PI_2,
    };
    assert_valid(
        &cfg,
        base,
        Point3::new(0.1, 6.0, 1.3),
        &[table(), base_body(&cfg, base)],
    );
}

#[test]
fn goal_inside_an_obstacle_is_a_collision() {
    let cfg = PlaceConfig::default();
    let base = near_base(0.7);
    let block = ObstacleBox::from_min_max(Point3::new(-0.3, 5.8, 0.0), Point3::new(0.3, 6.2, 1.35));
    assert_eq!(
        plan_place(&cfg, base, goal(), &[block]),
        Err(PlaceFailure::Collision)
    );
}

#[test]
fn a_wall_between_base_and_table_blocks_the_arm() {
    let cfg = PlaceConfig::default();
    let base = near_base(0.7);
    // A 2.5 m high screen across the reach, between the arm and the goal.
    let screen =
        ObstacleBox::from_min_max(Point3::new(-2.0, 5.6, 0.0), Point3::new(2.0, 5.65, 2.5));
    assert_eq!(
        plan_place(&cfg, base, goal(), &[table(), screen]),
        Err(PlaceFailure::Collision)
    );
    // The same screen lowered to 1.1 m: the arm reaches over it.
    let low = ObstacleBox::from_min_max(Point3::new(-2.0, 5.6, 0.0), Point3::new(2.0, 5.65, 1.1));
    assert_valid(&cfg, base, goal(), &[table(), low]);
}

#[test]
fn narrow_joint_limits_give_joint_limit_failure() {
    let mut cfg = PlaceConfig::default();
    // Elbow forced into a tiny range no placement uses.
    cfg.arm.limits.lower_rad[2] = 3.0;
    cfg.arm.limits.upper_rad[2] = 3.1;
    let base = near_base(0.7);
    assert_eq!(
        plan_place(&cfg, base, goal(), &[table()]),
        Err(PlaceFailure::JointLimits)
    );
}

#[test]
fn zero_tolerance_means_straight_down() {
    let cfg = PlaceConfig {
        down_tolerance_rad: 0.0,
        ..PlaceConfig::default()
    };
    let base = near_base(0.7);
    let plan = plan_place(&cfg, base, goal(), &[table()]).expect("placement");
    assert_eq!(plan.tool_tilt_rad, 0.0);
    let axis = plan.flange_world.rotation * Vector3::z();
    assert!((axis + Vector3::z()).norm() < 1e-9);
}

#[test]
fn tilt_extends_reach() {
    // Just beyond the straight-down reach, the tolerance makes the goal reachable, tilted.
    let straight = PlaceConfig {
        down_tolerance_rad: 0.0,
        ..PlaceConfig::default()
    };
    let tilted = PlaceConfig::default();
    // Arm axis 0.86 m from the goal.
    let base = near_base(PlaceConfig::default().mount.forward_m + 0.86);
    assert_eq!(
        plan_place(&straight, base, goal(), &[]),
        Err(PlaceFailure::OutOfReach)
    );
    let plan = plan_place(&tilted, base, goal(), &[]).expect("tilted placement");
    assert!(plan.tool_tilt_rad > 0.0);
}

#[test]
fn non_finite_input_fails_without_panic() {
    let cfg = PlaceConfig::default();
    let base = Pose2 {
        x_m: f64::NAN,
        ..near_base(0.7)
    };
    assert_eq!(
        plan_place(&cfg, base, goal(), &[]),
        Err(PlaceFailure::OutOfReach)
    );
    let g = Point3::new(0.0, f64::INFINITY, 1.3);
    assert_eq!(
        plan_place(&cfg, near_base(0.7), g, &[]),
        Err(PlaceFailure::OutOfReach)
    );
    let bad = PlaceConfig {
        tcp_offset_m: f64::NAN,
        ..PlaceConfig::default()
    };
    assert_eq!(
        plan_place(&bad, near_base(0.7), goal(), &[]),
        Err(PlaceFailure::OutOfReach)
    );
}

#[test]
fn validate_names_the_bad_field() {
    let mut cfg = PlaceConfig::default();
    cfg.collision.margin_m = -0.1;
    assert_eq!(cfg.validate().unwrap_err().field, "collision.margin_m");
    let cfg = PlaceConfig {
        down_tolerance_rad: 2.0,
        ..PlaceConfig::default()
    };
    assert_eq!(cfg.validate().unwrap_err().field, "down_tolerance_rad");
    let mut cfg = PlaceConfig::default();
    cfg.mount.height_m = f64::NAN;
    assert_eq!(cfg.validate().unwrap_err().field, "mount.height_m");
    let mut cfg = PlaceConfig::default();
    cfg.arm.limits.lower_rad[3] = 1.0;
    cfg.arm.limits.upper_rad[3] = 0.0;
    assert_eq!(cfg.validate().unwrap_err().field, "arm.limits");
}

#[test]
fn config_round_trips_through_json_and_rejects_unknown_fields() {
    let cfg = PlaceConfig::default();
    let text = serde_json::to_string(&cfg).expect("serialise");
    let back: PlaceConfig = serde_json::from_str(&text).expect("deserialise");
    assert_eq!(back, cfg);
    // Only the documented fields are required; the rest default.
    let minimal = r#"{"mount":{"forward_m":0.2,"lateral_m":0.0,"height_m":1.05,"yaw_rad":3.14159},
                      "tcp_offset_m":0.2,"down_tolerance_rad":0.17}"#;
    let parsed: PlaceConfig = serde_json::from_str(minimal).expect("minimal config");
    assert_eq!(parsed.arm, cfg.arm);
    let typo = r#"{"mount":{"forward_m":0.2,"lateral_m":0.0,"height_m":1.05,"yaw_rad":0.0},
                   "tcp_offset_m":0.2,"down_tolerance_rad":0.17,"tcp_ofset_m":1}"#;
    assert!(serde_json::from_str::<PlaceConfig>(typo).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Wherever a plan is returned it is valid; rotating the whole scene about the vertical
    /// does not change the outcome class.
    #[test]
    fn plans_are_valid_and_rotation_invariant(
        dx in -0.9..0.9f64, offset in 0.4..1.2f64, theta in -PI..PI,
    ) {
        let cfg = PlaceConfig::default();
        let base = Pose2 { x_m: dx, y_m: 6.0 - offset, yaw_rad: FRAC_PI_2 };
        let obstacles = [table(), base_body(&cfg, base)];
        let result = plan_place(&cfg, base, goal(), &obstacles);
        if result.is_ok() {
            assert_valid(&cfg, base, goal(), &obstacles);
        }
        // The same scene rotated by theta about the goal's vertical.
        let (s, c) = theta.sin_cos();
        let g = goal();
        let rot = |p: Point3<f64>| Point3::new(
            g.x + c * (p.x - g.x) - s * (p.y - g.y),
            g.y + s * (p.x - g.x) + c * (p.y - g.y),
            p.z,
        );
        let centre = rot(Point3::new(base.x_m, base.y_m, 0.0));
        let base_r = Pose2 { x_m: centre.x, y_m: centre.y, yaw_rad: base.yaw_rad + theta };
        let obstacles_r: Vec<ObstacleBox> = obstacles
            .iter()
            .map(|o| ObstacleBox { center: rot(o.center), yaw_rad: o.yaw_rad + theta, ..*o })
            .collect();
        let rotated = plan_place(&cfg, base_r, g, &obstacles_r);
        prop_assert_eq!(result.is_ok(), rotated.is_ok(), "{:?} vs {:?}", result, rotated);
    }
}
