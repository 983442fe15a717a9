//! The core's safety stops and the operator's enable (docs/runtime.md, "Safety stops and
//! holds"), on the same bench as the other reactions.

use super::*;

fn arm_in(safety_mode: i32, robot_mode: i32) -> Result<ArmSnapshot, ArmFault> {
    Ok(ArmSnapshot {
        safety_mode,
        robot_mode,
        ..ArmSnapshot::default()
    })
}

#[test]
fn a_start_is_not_an_enable_the_base_arms_only_after_the_operators_enable() {
    let mut b = Bench::new();
    for _ in 0..50 {
        b.step(|i| i.operator_enable = false);
        assert_eq!(b.out.base_mode, None, "no tractor before the enable");
        assert!(!b.out.rearm_base, "no re-arm before the enable");
        assert_eq!(b.out.velocity, Twist::ZERO);
        assert_eq!(b.core.state(), MissionState::Starting);
    }
    let waits = b
        .events
        .iter()
        .filter(|(k, d)| *k == EventKind::Enable && d.contains("waiting"))
        .count();
    assert_eq!(waits, 1, "the wait is reported once: {:?}", b.events);
    b.step(|i| i.operator_enable = true);
    assert_eq!(b.out.base_mode, Some(BaseMode::Tractor));
    assert!(b.out.rearm_base);
}

#[test]
fn a_safeguard_stop_pauses_until_it_clears_and_the_operator_enables() {
    let mut b = driving();
    let safeguard = arm_in(5, 7);
    b.step(|i| {
        i.arm = safeguard;
        i.operator_enable = false;
    });
    assert_eq!(b.out.velocity, Twist::ZERO, "the base stops at once");
    assert_eq!(b.out.arm, ArmCommand::Stop, "the arm is stopped");
    assert_eq!(b.core.state(), MissionState::Running, "paused, not ended");
    assert!(b.core.latch().is_some());
    // An enable while the safeguard is still open is refused.
    b.step(|i| {
        i.arm = safeguard;
        i.operator_enable = true;
    });
    assert_eq!(b.out.velocity, Twist::ZERO);
    assert!(
        b.events
            .iter()
            .any(|(k, d)| *k == EventKind::Enable && d.contains("refused")),
        "{:?}",
        b.events
    );
    // The safeguard closes: nothing moves until the operator enables.
    for _ in 0..100 {
        b.step(|i| {
            i.arm = arm_in(1, 7);
            i.operator_enable = false;
        });
        assert_eq!(b.out.velocity, Twist::ZERO, "latched until the enable");
        assert!(b.out.job.is_none());
    }
    assert!(b.core.latch().is_some_and(|l| l.cleared));
    // The enable: the leg starts over from where the base stands (a new path).
    b.step(|i| {
        i.arm = arm_in(1, 7);
        i.operator_enable = true;
    });
    assert!(b.core.latch().is_none());
    let mut job = b.out.job;
    for _ in 0..5 {
        if job.is_some() {
            break;
        }
        b.step(|i| i.arm = arm_in(1, 7));
        job = b.out.job;
    }
    let Some(Job::Path { id, from, to, .. }) = job else {
        panic!("the leg asks for a new path after the enable: {job:?}");
    };
    let answer = Answer::Path(id, Ok(straight_path(from, to)));
    b.step(|i| {
        i.arm = arm_in(1, 7);
        i.answer = Some(&answer);
    });
    for _ in 0..20 {
        b.step(|i| i.arm = arm_in(1, 7));
    }
    assert!(b.out.velocity.speed_mps > 0.05, "{:?}", b.out.velocity);
}

#[test]
fn every_other_arm_safety_mode_and_a_robot_mode_off_running_end_the_mission() {
    // Recovery, violation, fault, validate joint id, undefined.
    for mode in [4, 8, 9, 10, 11] {
        let mut b = driving();
        b.step(|i| i.arm = arm_in(mode, 7));
        assert_eq!(
            b.core.state(),
            MissionState::Aborted(AbortReason::ArmUnsafe),
            "safety mode {mode}"
        );
        assert_eq!(b.out.velocity, Twist::ZERO);
        assert_eq!(b.out.arm, ArmCommand::Stop);
    }
    // Emergency stops by mode alone (no status bit).
    for mode in [3, 6, 7] {
        let mut b = driving();
        b.step(|i| i.arm = arm_in(mode, 7));
        assert_eq!(
            b.core.state(),
            MissionState::Aborted(AbortReason::ArmStopped),
            "safety mode {mode}"
        );
    }
    // Powered off after it ran.
    let mut b = driving();
    b.step(|i| i.arm = arm_in(1, 7));
    b.step(|i| i.arm = arm_in(1, 3));
    assert_eq!(
        b.core.state(),
        MissionState::Aborted(AbortReason::ArmUnsafe)
    );
    assert_eq!(b.out.velocity, Twist::ZERO);
}

#[test]
fn a_base_that_leaves_tractor_mode_unasked_is_a_safety_stop() {
    let mut b = driving();
    b.tractor = false;
    b.step(|_| {});
    assert_eq!(
        b.core.state(),
        MissionState::Aborted(AbortReason::BaseModeLost)
    );
    assert_eq!(b.out.velocity, Twist::ZERO);
    // Tractor back: nothing drives again (no re-arm, no mode asked).
    b.tractor = true;
    for _ in 0..20 {
        b.step(|_| {});
        assert_eq!(b.out.velocity, Twist::ZERO);
        assert!(!b.out.rearm_base);
        assert_eq!(b.out.base_mode, None);
    }
}

#[test]
fn a_latched_stop_asks_the_base_for_its_safety_stop_and_a_hold_does_not() {
    // Operational holds: the collision monitor's stop and a stale scan, waiting for a path.
    let mut b = driving();
    for monitor in [MonitorAction::Stop, MonitorAction::Stale] {
        for _ in 0..10 {
            b.step(|i| i.monitor = monitor);
            assert!(!b.out.safety_stop, "{monitor:?} is a hold");
        }
    }
    for _ in 0..10 {
        b.step(|_| {});
        assert!(!b.out.safety_stop);
    }
    // A UR safeguard stop latches: the base's safety stop; the enable once it cleared re-arms.
    b.step(|i| {
        i.arm = arm_in(5, 7);
        i.operator_enable = false;
    });
    assert!(b.out.safety_stop, "a safeguard stop is a safety stop");
    b.step(|i| {
        i.arm = arm_in(1, 7);
        i.operator_enable = false;
    });
    assert!(!b.out.rearm_base, "no re-arm before the enable");
    b.step(|i| {
        i.arm = arm_in(1, 7);
        i.operator_enable = true;
    });
    assert!(b.core.latch().is_none());
    assert!(
        b.out.rearm_base,
        "the enable releases the base's safety stop"
    );
    assert!(!b.out.safety_stop);
    // Aborts for a safety cause: a base that does not keep its stored limits, a lost mode.
    let limit = Err(BaseError::LimitChanged {
        setting: rmp_codec::v3::NvmFloat::MaxVelocityMps,
        verified: 0.4,
        reported: 2.2352,
    });
    let mut b = driving();
    b.step(|i| i.base_tick = Some(&limit));
    assert_eq!(
        b.core.state(),
        MissionState::Aborted(AbortReason::BaseFault)
    );
    assert!(b.out.safety_stop);
    let mut b = driving();
    b.tractor = false;
    b.step(|_| {});
    assert!(b.out.safety_stop, "a mode drop is a safety stop");
    // The operator's shutdown is not.
    let mut b = driving();
    b.step(|i| i.shutdown = true);
    assert_eq!(b.core.state(), MissionState::Aborted(AbortReason::Shutdown));
    assert!(!b.out.safety_stop);
}
