//! Unit and property tests of the wrap and the poses.

use super::*;
use core::f64::consts::{FRAC_PI_2, PI, TAU};
use proptest::prelude::*;

#[test]
fn wrap_is_half_open_at_pi() {
    assert_eq!(wrap_angle(PI), PI);
    assert_eq!(wrap_angle(-PI), PI);
    assert_eq!(wrap_angle(3.0 * PI), PI);
    assert_eq!(wrap_angle(-3.0 * PI), PI);
    assert_eq!(wrap_angle(TAU), 0.0);
    assert_eq!(wrap_angle_f32(core::f32::consts::PI), core::f32::consts::PI);
    assert_eq!(
        wrap_angle_f32(-core::f32::consts::PI),
        core::f32::consts::PI
    );
}

#[test]
fn wrap_keeps_angles_in_zero_to_pi_and_rounds_negative_ones_near_tau() {
    for a in [0.0, 0.5, 1e-300, FRAC_PI_2, PI - 1e-15] {
        assert_eq!(wrap_angle(a).to_bits(), a.to_bits(), "{a}");
    }
    // A negative angle goes through a + TAU: rounded to the float spacing near TAU.
    let spacing = 8.9e-16;
    for a in [-0.5, -FRAC_PI_2, -PI + 1e-15, -1e-9] {
        assert!((wrap_angle(a) - a).abs() <= spacing, "{a}");
    }
    assert_eq!(wrap_angle(-1e-300), 0.0, "rounds up to a whole turn");
    assert!((wrap_angle(TAU + 0.1) - 0.1).abs() < 1e-15);
    assert!((wrap_angle(-TAU - 0.1) + 0.1).abs() < 1e-15);
    assert!((wrap_angle(3.0 * TAU + 0.5) - 0.5).abs() < 1e-14);
    assert!((wrap_angle(-FRAC_PI_2 - TAU) + FRAC_PI_2).abs() < 1e-15);
    assert!((wrap_angle_f32(2.0 * core::f32::consts::PI + 0.1) - 0.1).abs() < 1e-6);
    let f = wrap_angle_f32(-core::f32::consts::FRAC_PI_2);
    assert!((f + core::f32::consts::FRAC_PI_2).abs() <= 4.8e-7);
}

#[test]
fn wrap_is_the_arithmetic_ur5e_kin_had() {
    // ur5e-kin's wrap_to_pi, as it was: its IK branch choices depend on these bits.
    fn had(a: f64) -> f64 {
        let mut w = a.rem_euclid(TAU);
        if w > PI {
            w -= TAU;
        }
        w
    }
    for k in -2000..2000 {
        let a = f64::from(k) * 0.0137 + 1e-3 * f64::from(k % 7);
        assert_eq!(wrap_angle(a).to_bits(), had(a).to_bits(), "{a}");
    }
}

#[test]
fn wrap_of_nan_and_infinities_is_nan() {
    assert!(wrap_angle(f64::NAN).is_nan());
    assert!(wrap_angle(f64::INFINITY).is_nan());
    assert!(wrap_angle(f64::NEG_INFINITY).is_nan());
    assert!(wrap_angle_f32(f32::INFINITY).is_nan());
}

#[test]
fn compose_and_inverse_by_hand() {
    let a = Pose2::new(1.0, 2.0, FRAC_PI_2);
    let b = Pose2::new(1.0, 0.0, FRAC_PI_2);
    let c = a.compose(&b);
    assert!((c.x_m - 1.0).abs() < 1e-12 && (c.y_m - 3.0).abs() < 1e-12);
    assert_eq!(c.yaw_rad, PI);
    // Turning on past pi wraps.
    let d = c.compose(&Pose2::new(0.0, 0.0, FRAC_PI_2));
    assert!((d.yaw_rad + FRAC_PI_2).abs() < 1e-12);
    let inv = a.inverse();
    assert!((inv.x_m + 2.0).abs() < 1e-12 && (inv.y_m - 1.0).abs() < 1e-12);
    assert_eq!(inv.yaw_rad, -FRAC_PI_2);
}

#[test]
fn point_transforms_are_inverse_to_each_other() {
    let p = Pose2::new(-3.0, 0.5, 2.0);
    let (x, y) = p.transform_point(0.7, -1.1);
    let (lx, ly) = p.inverse_transform_point(x, y);
    assert!((lx - 0.7).abs() < 1e-12 && (ly + 1.1).abs() < 1e-12);
    // The pose's own position is its frame's origin.
    assert_eq!(p.inverse_transform_point(p.x_m, p.y_m), (0.0, 0.0));
    // A point transformed is the pose composed with a pose at that point.
    let q = p.compose(&Pose2::new(0.7, -1.1, 0.0));
    assert_eq!((q.x_m, q.y_m), (x, y));
}

#[test]
fn distance_and_finiteness() {
    assert_eq!(
        Pose2::new(0.0, 0.0, 1.0).distance_m(&Pose2::new(3.0, 4.0, -1.0)),
        5.0
    );
    assert!(Pose2::IDENTITY.is_finite());
    assert!(!Pose2::new(0.0, f64::NAN, 0.0).is_finite());
    assert!(!Pose2F32::new(0.0, 0.0, f32::INFINITY).is_finite());
    assert_eq!(Pose2::default(), Pose2::IDENTITY);
}

#[test]
fn advance_along_a_quarter_circle_and_a_line() {
    // Radius 1 m: a quarter arc ends at (1, 1) facing +y.
    let q = Pose2::IDENTITY.advance(FRAC_PI_2, FRAC_PI_2);
    assert!((q.x_m - 1.0).abs() < 1e-12 && (q.y_m - 1.0).abs() < 1e-12);
    assert!((q.yaw_rad - FRAC_PI_2).abs() < 1e-12);
    let s = Pose2::new(1.0, 1.0, FRAC_PI_2).advance(2.0, 0.0);
    assert!((s.x_m - 1.0).abs() < 1e-12 && (s.y_m - 3.0).abs() < 1e-12);
    let f = Pose2F32::IDENTITY.advance(core::f32::consts::FRAC_PI_2, core::f32::consts::FRAC_PI_2);
    assert!((f.x_m - 1.0).abs() < 1e-6 && (f.y_m - 1.0).abs() < 1e-6);
}

#[test]
fn f32_and_f64_convert() {
    let p = Pose2F32::new(1.5, -2.25, 0.5);
    assert_eq!(Pose2::from(p).to_f32(), p);
}

#[cfg(feature = "serde")]
#[test]
fn serde_field_names_are_the_files() {
    let p: Pose2 =
        serde_json::from_str(r#"{"x_m": 0.0, "y_m": 2.0, "yaw_rad": 1.5}"#).expect("a pose");
    assert_eq!(p, Pose2::new(0.0, 2.0, 1.5));
    assert_eq!(
        serde_json::to_string(&p).expect("json"),
        r#"{"x_m":0.0,"y_m":2.0,"yaw_rad":1.5}"#
    );
    let unknown = serde_json::from_str::<Pose2>(r#"{"x_m": 0, "y_m": 0, "yaw_rad": 0, "z_m": 1}"#);
    assert!(unknown.is_err());
}

proptest! {
    #[test]
    fn wrap_is_in_range_idempotent_and_a_whole_number_of_turns(a in -1e6f64..1e6) {
        let w = wrap_angle(a);
        prop_assert!(w > -PI && w <= PI, "{a} -> {w}");
        prop_assert_eq!(wrap_angle(w).to_bits(), w.to_bits());
        let turns = (a - w) / TAU;
        prop_assert!((turns - turns.round()).abs() < 1e-9, "{a} -> {w}: {turns} turns");
        // The sine and cosine are the angle's (to the float TAU's error times the turns).
        prop_assert!((w.sin() - a.sin()).abs() < 1e-9 && (w.cos() - a.cos()).abs() < 1e-9);
    }

    #[test]
    fn wrap_f32_is_in_range_and_idempotent(a in -1e4f32..1e4) {
        use core::f32::consts::PI;
        let w = wrap_angle_f32(a);
        prop_assert!(w > -PI && w <= PI, "{a} -> {w}");
        prop_assert_eq!(wrap_angle_f32(w).to_bits(), w.to_bits());
    }

    #[test]
    fn compose_with_inverse_is_the_identity(
        x in -100.0f64..100.0, y in -100.0f64..100.0, yaw in -10.0f64..10.0,
    ) {
        let p = Pose2::new(x, y, yaw);
        for id in [p.compose(&p.inverse()), p.inverse().compose(&p)] {
            prop_assert!(id.distance_m(&Pose2::IDENTITY) < 1e-12, "{id:?}");
            prop_assert!(id.yaw_rad.abs() < 1e-12, "{id:?}");
        }
    }

    #[test]
    fn compose_is_associative(
        a in (-10.0f64..10.0, -10.0f64..10.0, -4.0f64..4.0),
        b in (-10.0f64..10.0, -10.0f64..10.0, -4.0f64..4.0),
        c in (-10.0f64..10.0, -10.0f64..10.0, -4.0f64..4.0),
    ) {
        let (a, b, c) = (Pose2::new(a.0, a.1, a.2), Pose2::new(b.0, b.1, b.2), Pose2::new(c.0, c.1, c.2));
        let l = a.compose(&b).compose(&c);
        let r = a.compose(&b.compose(&c));
        prop_assert!(l.distance_m(&r) < 1e-9);
        prop_assert!(wrap_angle(l.yaw_rad - r.yaw_rad).abs() < 1e-9);
    }
}
