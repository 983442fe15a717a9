//! RRT-Connect joint paths: valid, collision-free between waypoints, deterministic per seed.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use nalgebra::{Point3, Vector3};
use planar::Pose2;
use ur5e_kin::{
    JointPathError, Joints, ObstacleBox, PlaceConfig, arm_collides, plan_joint_path, plan_place,
};

fn base() -> Pose2 {
    Pose2 {
        x_m: 0.0,
        y_m: 0.0,
        yaw_rad: 0.0,
    }
}

/// A pole 1.5 m high in front of the robot, a wall behind it and the robot's own body. The
/// straight joint-space segment between the two placements turns q1 the long way, through the
/// wall; the way round the front passes the pole.
fn obstacles(cfg: &PlaceConfig) -> Vec<ObstacleBox> {
    vec![
        ObstacleBox::from_min_max(Point3::new(-0.45, -1.5, 0.0), Point3::new(-0.35, 1.5, 2.5)),
        ObstacleBox {
            center: Point3::new(0.78, 0.0, 0.75),
            half_extents: Vector3::new(0.05, 0.05, 0.75),
            yaw_rad: 0.0,
        },
        ObstacleBox {
            center: Point3::new(0.0, 0.0, 0.5 * cfg.mount.height_m),
            half_extents: Vector3::new(0.30, 0.275, 0.5 * cfg.mount.height_m),
            yaw_rad: 0.0,
        },
    ]
}

/// Tool-down configurations on either side of the pole.
fn start_and_goal(cfg: &PlaceConfig, obs: &[ObstacleBox]) -> (Joints, Joints) {
    let left = plan_place(cfg, base(), Point3::new(0.6, 0.45, 1.3), obs).expect("left");
    let right = plan_place(cfg, base(), Point3::new(0.6, -0.45, 1.3), obs).expect("right");
    (left.joints, right.joints)
}

/// Checks every segment at 0.01 rad, five times finer than the planner does.
fn assert_path_free(cfg: &PlaceConfig, path: &[Joints], obs: &[ObstacleBox]) {
    for w in path.windows(2) {
        let d = w[0]
            .iter()
            .zip(&w[1])
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let steps = (d / 0.01).ceil().max(1.0) as usize;
        for k in 0..=steps {
            let t = k as f64 / steps as f64;
            let q: Joints = core::array::from_fn(|i| w[0][i] + (w[1][i] - w[0][i]) * t);
            assert!(cfg.arm.limits.contains(&q));
            assert!(!arm_collides(cfg, base(), &q, obs), "collision at {q:?}");
        }
    }
}

fn segment_blocked(cfg: &PlaceConfig, a: &Joints, b: &Joints, obs: &[ObstacleBox]) -> bool {
    (0..=200).any(|k| {
        let t = k as f64 / 200.0;
        let q: Joints = core::array::from_fn(|i| a[i] + (b[i] - a[i]) * t);
        arm_collides(cfg, base(), &q, obs)
    })
}

#[test]
fn finds_a_path_around_a_pole() {
    let cfg = PlaceConfig::default();
    let obs = obstacles(&cfg);
    let (start, goal) = start_and_goal(&cfg, &obs);
    assert!(
        segment_blocked(&cfg, &start, &goal, &obs),
        "scenario must need a detour"
    );
    let path = plan_joint_path(&cfg, base(), &start, &goal, &obs, 7).expect("path");
    assert_eq!(path.first(), Some(&start));
    assert_eq!(path.last(), Some(&goal));
    assert!(path.len() >= 3);
    assert_path_free(&cfg, &path, &obs);
}

#[test]
fn same_seed_same_path_other_seed_still_valid() {
    let cfg = PlaceConfig::default();
    let obs = obstacles(&cfg);
    let (start, goal) = start_and_goal(&cfg, &obs);
    let a = plan_joint_path(&cfg, base(), &start, &goal, &obs, 11).expect("path");
    let b = plan_joint_path(&cfg, base(), &start, &goal, &obs, 11).expect("path");
    assert_eq!(a, b);
    let c = plan_joint_path(&cfg, base(), &start, &goal, &obs, 12).expect("path");
    assert_path_free(&cfg, &c, &obs);
}

#[test]
fn free_space_gives_the_straight_segment() {
    let cfg = PlaceConfig::default();
    let (start, goal) = start_and_goal(&cfg, &[]);
    let path = plan_joint_path(&cfg, base(), &start, &goal, &[], 0).expect("path");
    assert_eq!(path, vec![start, goal]);
}

#[test]
fn invalid_endpoints_are_reported() {
    let cfg = PlaceConfig::default();
    let obs = obstacles(&cfg);
    let (start, goal) = start_and_goal(&cfg, &obs);
    let mut beyond = start;
    beyond[2] = 4.0; // elbow past its +-pi limit
    assert_eq!(
        plan_joint_path(&cfg, base(), &beyond, &goal, &obs, 0),
        Err(JointPathError::InvalidStart)
    );
    let mut nan = goal;
    nan[0] = f64::NAN;
    assert_eq!(
        plan_joint_path(&cfg, base(), &start, &nan, &obs, 0),
        Err(JointPathError::InvalidGoal)
    );
    // Arm straight down into the floor.
    let into_floor = [0.0, 1.4, 0.0, 0.0, 0.0, 0.0];
    assert!(arm_collides(&cfg, base(), &into_floor, &obs));
    assert_eq!(
        plan_joint_path(&cfg, base(), &into_floor, &goal, &obs, 0),
        Err(JointPathError::InvalidStart)
    );
}

#[test]
fn exhausted_budget_is_no_path() {
    let mut cfg = PlaceConfig::default();
    cfg.path.max_samples = 2;
    let obs = obstacles(&cfg);
    let (start, goal) = start_and_goal(&cfg, &obs);
    assert_eq!(
        plan_joint_path(&cfg, base(), &start, &goal, &obs, 5),
        Err(JointPathError::NoPath { samples: 2 })
    );
}

#[test]
fn from_upright_carry_pose_to_a_table_placement() {
    use core::f64::consts::FRAC_PI_2;
    // The planner crate's carry pose: upper arm and forearm straight up.
    let carry: Joints = [0.0, -FRAC_PI_2, 0.0, -FRAC_PI_2, 0.0, 0.0];
    let cfg = PlaceConfig::default();
    for (offset, dx) in [(0.6, 0.0), (0.8, 0.3), (0.9, -0.2)] {
        let base = Pose2 {
            x_m: dx,
            y_m: 6.0 - offset,
            yaw_rad: FRAC_PI_2,
        };
        let obs = vec![
            ObstacleBox::from_min_max(Point3::new(-1.5, 5.8, 0.0), Point3::new(1.5, 6.2, 1.0)),
            ObstacleBox {
                center: Point3::new(base.x_m, base.y_m, 0.5 * cfg.mount.height_m),
                half_extents: Vector3::new(0.30, 0.275, 0.5 * cfg.mount.height_m),
                yaw_rad: base.yaw_rad,
            },
        ];
        assert!(
            !arm_collides(&cfg, base, &carry, &obs),
            "carry pose must be free"
        );
        let place = plan_place(&cfg, base, Point3::new(0.0, 6.0, 1.3), &obs).expect("place");
        let path = plan_joint_path(&cfg, base, &carry, &place.joints, &obs, 1).expect("path");
        assert_eq!(path.first(), Some(&carry));
        assert_eq!(path.last(), Some(&place.joints));
        for w in path.windows(2) {
            let d = w[0]
                .iter()
                .zip(&w[1])
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            let steps = (d / 0.01).ceil().max(1.0) as usize;
            for k in 0..=steps {
                let t = k as f64 / steps as f64;
                let q: Joints = core::array::from_fn(|i| w[0][i] + (w[1][i] - w[0][i]) * t);
                assert!(!arm_collides(&cfg, base, &q, &obs), "collision at {q:?}");
            }
        }
    }
}
