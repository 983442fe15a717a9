//! FK/IK round trips as properties, and IK on known UR5e poses.

use core::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion, Vector3};
use planar::wrap_angle;
use proptest::prelude::*;
use ur5e_kin::{Joints, Ur5e};

fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    (
        (a.translation.vector - b.translation.vector).norm(),
        a.rotation.angle_to(&b.rotation),
    )
}

fn same_angles(a: &Joints, b: &Joints, tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| wrap_angle(x - y).abs() < tol)
}

/// Joint values away from the wrist singularity (|sin q5| small) where q6 is not unique.
fn joints_strategy() -> impl Strategy<Value = Joints> {
    (
        -PI..PI,
        -PI..PI,
        -PI..PI,
        -PI..PI,
        prop_oneof![0.05..(PI - 0.05), -(PI - 0.05)..-0.05],
        -PI..PI,
    )
        .prop_map(|(a, b, c, d, e, f)| [a, b, c, d, e, f])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Every IK solution reproduces the pose, and the configuration it came from is among them.
    #[test]
    fn ik_solutions_reproduce_fk(q in joints_strategy()) {
        let arm = Ur5e::default();
        let pose = arm.forward(&q);
        let solutions = arm.inverse(&pose);
        prop_assert!(!solutions.is_empty(), "no IK solution for q = {:?}", q);
        for s in &solutions {
            prop_assert!(arm.limits.contains(s));
            let (dp, dr) = pose_error(&arm.forward(s), &pose);
            prop_assert!(dp < 1e-7 && dr < 1e-7, "solution {:?} misses by {} m, {} rad", s, dp, dr);
        }
        prop_assert!(
            solutions.iter().any(|s| same_angles(s, &q, 1e-6)),
            "original q = {:?} not among {:?}", q, solutions
        );
    }

    /// Random reachable poses given as positions and orientations round-trip through IK then FK.
    #[test]
    fn fk_of_ik_is_identity_on_random_poses(
        x in -0.6..0.6f64, y in -0.6..0.6f64, z in -0.2..0.7f64,
        roll in -PI..PI, pitch in -1.5..1.5f64, yaw in -PI..PI,
    ) {
        let arm = Ur5e::default();
        let pose = Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        );
        for s in &arm.inverse(&pose) {
            let (dp, dr) = pose_error(&arm.forward(s), &pose);
            prop_assert!(dp < 1e-7 && dr < 1e-7);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// Near the wrist singularity (q5 ~ 0) and the stretched elbow (q3 ~ 0) the solutions still
    /// reproduce the pose (q6 may differ from the original: there it is not unique).
    #[test]
    fn ik_is_accurate_near_singularities(
        q1 in -PI..PI, q2 in -PI..PI, q3 in -0.02..0.02f64, q4 in -PI..PI,
        q5 in -0.02..0.02f64, q6 in -PI..PI,
    ) {
        let arm = Ur5e::default();
        let q = [q1, q2, q3, q4, q5, q6];
        let pose = arm.forward(&q);
        let solutions = arm.inverse(&pose);
        prop_assert!(!solutions.is_empty(), "no solution near singularity for {:?}", q);
        for s in &solutions {
            let (dp, dr) = pose_error(&arm.forward(s), &pose);
            prop_assert!(dp < 1e-6 && dr < 1e-6, "{:?}: {} m {} rad", s, dp, dr);
        }
    }
}

#[test]
fn generic_pose_has_eight_distinct_solutions() {
    let arm = Ur5e::default();
    // Wrist close to the base axis: both shoulder branches reach it.
    let q = [0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0];
    let solutions = arm.inverse(&arm.forward(&q));
    assert_eq!(solutions.len(), 8);
    for (i, a) in solutions.iter().enumerate() {
        for b in solutions.iter().skip(i + 1) {
            assert!(!same_angles(a, b, 1e-6), "duplicate solution {a:?}");
        }
    }
}

#[test]
fn ik_on_reference_poses() {
    let arm = Ur5e::default();
    // Test vectors of shared/reference/ur5e.md section 5.1; the middle one is the upright
    // "home" with q5 = 0 (wrist singular, q6 set to 0 by convention).
    for q in [
        [0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0],
        [0.0, -FRAC_PI_2, 0.0, -FRAC_PI_2, 0.0, 0.0],
    ] {
        let pose = arm.forward(&q);
        let solutions = arm.inverse(&pose);
        assert!(!solutions.is_empty());
        for s in &solutions {
            let (dp, dr) = pose_error(&arm.forward(s), &pose);
            assert!(dp < 1e-7 && dr < 1e-7, "{s:?}: {dp} m {dr} rad");
        }
        assert!(
            solutions.iter().any(|s| same_angles(s, &q, 1e-6)),
            "{q:?} missing in {solutions:?}"
        );
    }
}

#[test]
fn tool_down_pose_in_front_is_reachable_and_far_pose_is_not() {
    let arm = Ur5e::default();
    let down =
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_axis_angle(&Vector3::x_axis(), PI));
    let near = Isometry3::from_parts(Translation3::new(0.5, 0.0, 0.3), down);
    assert!(!arm.inverse(&near).is_empty());
    let far = Isometry3::from_parts(Translation3::new(1.2, 0.0, 0.3), down);
    assert!(arm.inverse(&far).is_empty());
    // On the base axis the wrist centre is inside the shoulder-offset cylinder.
    let on_axis = Isometry3::from_parts(Translation3::new(0.0, 0.0, 0.5), down);
    assert!(arm.inverse(&on_axis).is_empty());
}

#[test]
fn narrower_limits_drop_solutions() {
    let mut arm = Ur5e::default();
    let q = [0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0];
    let pose = arm.forward(&q);
    arm.limits.lower_rad[2] = 0.0; // elbow only positive
    let solutions = arm.inverse(&pose);
    assert_eq!(solutions.len(), 4);
    assert!(solutions.iter().all(|s| s[2] >= 0.0));
}
