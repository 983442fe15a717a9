//! Properties of the limiter and the watchdog for arbitrary inputs, NaN included.

use motion_control::Twist;
use motion_control::limiter::{TwistLimiter, TwistLimits};
use motion_control::watchdog::Watchdog;
use proptest::prelude::*;

fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        -5.0f32..5.0,
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY)
    ]
}

proptest! {
    #[test]
    fn limiter_output_stays_in_the_envelope_and_rate(
        targets in proptest::collection::vec((any_f32(), any_f32(), 0.0f32..0.1), 1..200),
    ) {
        let limits = TwistLimits::default();
        let mut l = TwistLimiter::new(limits);
        let mut prev = Twist::ZERO;
        for (v, w, dt) in targets {
            let out = l.step(Twist::new(v, w), dt);
            prop_assert!(out.is_finite());
            prop_assert!(out.speed_mps <= limits.max_forward_mps + 1e-6);
            prop_assert!(out.speed_mps >= -limits.max_reverse_mps - 1e-6);
            prop_assert!(out.yaw_rate_radps.abs() <= limits.max_yaw_rate_radps + 1e-6);
            let max_dv = limits.max_accel_mps2.max(limits.max_decel_mps2) * dt + 1e-5;
            prop_assert!((out.speed_mps - prev.speed_mps).abs() <= max_dv);
            let max_dw = limits.max_yaw_accel_radps2 * dt + 1e-5;
            prop_assert!((out.yaw_rate_radps - prev.yaw_rate_radps).abs() <= max_dw);
            prev = out;
        }
    }

    #[test]
    fn watchdog_is_stale_exactly_past_the_timeout(
        timeout in 1u64..1_000_000, fed in 0u64..1_000_000, later in 0u64..3_000_000,
    ) {
        let mut w = Watchdog::new(timeout);
        prop_assert!(w.is_stale(fed));
        w.feed(fed);
        prop_assert_eq!(w.is_stale(fed + later), later > timeout);
    }
}
