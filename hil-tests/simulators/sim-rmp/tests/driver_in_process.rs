//! The real driver against the simulated base on the in-memory bus, on a simulated clock:
//! deterministic, no sleeping. Odometry against ground truth, the base's own loss-of-command
//! ramp when the host dies, faults, the yaw sign, and determinism.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::time::Duration;

use can_bus::{MemoryBus, MemoryBusNode};
use motion_control::Twist;
use planar::Pose2;
use rmp_base::{BaseError, BaseMode, CanLink, Odometry, RmpBase, RmpBaseConfig};
use rmp_codec::faults;
use rmp_codec::v3::{NvmFloat, OperationalState};
use sim_rmp::{SimConfig, SimRmp, SimRmpNode};

const PERIOD: Duration = Duration::from_millis(20);

struct Rig {
    sim: SimRmpNode<MemoryBusNode>,
    driver: RmpBase<CanLink<MemoryBusNode>>,
    now: Duration,
}

impl Rig {
    fn new(yaw_sign: f64) -> Self {
        let bus = MemoryBus::new();
        let sim = SimRmpNode::new(
            bus.join(),
            SimRmp::new(SimConfig {
                yaw_sign,
                ..SimConfig::default()
            }),
        );
        let driver = RmpBase::new(
            CanLink::new(bus.join()),
            RmpBaseConfig {
                yaw_sign,
                ..RmpBaseConfig::default()
            },
        )
        .unwrap();
        Self {
            sim,
            driver,
            now: Duration::ZERO,
        }
    }

    /// One 20 ms period: the driver ticks, the base answers (and moves) up to the next tick.
    fn step(&mut self) -> Result<rmp_base::Tick, BaseError> {
        let r = self.driver.tick(self.now);
        // The base answers 1 ms after the command, as on a real bus.
        self.sim.poll(self.now + Duration::from_millis(1)).unwrap();
        self.now += PERIOD;
        self.sim.poll(self.now).unwrap();
        r
    }

    fn drive(&mut self, twist: Twist, duration: Duration) {
        let end = self.now + duration;
        while self.now < end {
            self.driver.set_velocity(twist, self.now);
            self.step().unwrap();
        }
    }

    fn enter_tractor(&mut self) {
        self.driver.request_mode(BaseMode::Tractor, self.now);
        for _ in 0..100 {
            if self.step().unwrap().mode_reached == Some(BaseMode::Tractor) {
                return;
            }
        }
        panic!("no tractor");
    }
}

fn mission(yaw_sign: f64) -> (Odometry, Pose2) {
    let mut rig = Rig::new(yaw_sign);
    rig.enter_tractor();
    assert_eq!(rig.sim.sim().state(), OperationalState::Tractor);
    rig.drive(Twist::new(0.4, 0.0), Duration::from_secs(2));
    rig.drive(Twist::new(0.0, 0.8), Duration::from_secs(2));
    rig.drive(Twist::new(0.3, 0.3), Duration::from_secs(2));
    // Let the watchdog and the limiter bring it to rest, then one more reply.
    for _ in 0..60 {
        rig.step().unwrap();
    }
    (*rig.driver.odometry(), rig.sim.sim().pose())
}

#[test]
fn odometry_tracks_ground_truth_through_a_mission() {
    let (odo, truth) = mission(1.0);
    assert!(
        truth.x_m.hypot(truth.y_m) > 0.6,
        "the base moved: {truth:?}"
    );
    assert!(truth.yaw_rad > 1.0, "counter-clockwise turn: {truth:?}");
    // Odometry differences float32 integrators, so millimetres.
    assert!((odo.x_m - truth.x_m).abs() < 0.005, "{odo:?} vs {truth:?}");
    assert!((odo.y_m - truth.y_m).abs() < 0.005, "{odo:?} vs {truth:?}");
    assert!(
        (odo.yaw_rad - truth.yaw_rad).abs() < 0.005,
        "{odo:?} vs {truth:?}"
    );
    assert_eq!(odo.speed_mps, 0.0);
}

#[test]
fn a_clockwise_positive_base_still_turns_the_way_the_caller_asked() {
    let (odo, truth) = mission(-1.0);
    assert!(
        truth.yaw_rad > 1.0,
        "counter-clockwise in the world: {truth:?}"
    );
    assert!((odo.yaw_rad - truth.yaw_rad).abs() < 0.005);
}

#[test]
fn the_same_mission_twice_gives_bit_identical_results() {
    let a = mission(1.0);
    let b = mission(1.0);
    assert_eq!(format!("{a:?}"), format!("{b:?}"));
}

#[test]
fn when_the_host_dies_the_base_holds_then_ramps_to_zero_at_its_decel_limit() {
    let mut rig = Rig::new(1.0);
    rig.enter_tractor();
    rig.drive(Twist::new(0.5, 0.0), Duration::from_secs(2));
    let cruise = rig.sim.sim().velocity().0;
    assert!((cruise - 0.5).abs() < 1e-3);
    // The host process is gone: no more ticks. Only the base's clock runs.
    let died = rig.now;
    rig.sim.poll(died + Duration::from_millis(480)).unwrap();
    assert_eq!(rig.sim.sim().velocity().0, cruise, "held for 0.5 s");
    rig.sim.poll(died + Duration::from_millis(560)).unwrap();
    let v = rig.sim.sim().velocity().0;
    assert!(v < cruise && v > 0.0, "ramping, not a jump: {v}");
    // 0.5 m/s at 3.923 m/s^2: at rest 0.13 s after the timeout.
    rig.sim.poll(died + Duration::from_millis(700)).unwrap();
    assert_eq!(rig.sim.sim().velocity().0, 0.0);
}

#[test]
fn an_injected_kill_switch_stops_the_base_and_the_driver_names_it() {
    let mut rig = Rig::new(1.0);
    rig.enter_tractor();
    rig.drive(Twist::new(0.4, 0.0), Duration::from_secs(1));
    rig.sim
        .sim_mut()
        .set_fault(faults::KILL_SWITCH_ACTIVE, true);
    let mut named = false;
    for _ in 0..50 {
        rig.driver.set_velocity(Twist::new(0.4, 0.0), rig.now);
        if let Err(BaseError::Faulted { faults }) = rig.step() {
            named |= faults.has(faults::KILL_SWITCH_ACTIVE);
        }
    }
    assert!(named);
    assert_eq!(rig.sim.sim().velocity().0, 0.0);
    assert!(!rig.driver.is_driving() || rig.driver.status().faults.stops_motion());
}

#[test]
fn a_silenced_base_is_reported_and_recovers_after_rearm() {
    let mut rig = Rig::new(1.0);
    rig.enter_tractor();
    rig.drive(Twist::new(0.3, 0.0), Duration::from_millis(500));
    rig.sim.sim_mut().set_silent(true);
    let mut silent_errors = 0;
    for _ in 0..30 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        if let Err(BaseError::Silent { .. }) = rig.step() {
            silent_errors += 1;
        }
    }
    assert!(silent_errors >= 15, "{silent_errors}");
    rig.sim.sim_mut().set_silent(false);
    rig.step().ok();
    // The link came back, but motion resumes only after an explicit re-arm.
    rig.drive(Twist::new(0.3, 0.0), Duration::from_millis(500));
    assert_eq!(rig.sim.sim().velocity().0, 0.0);
    assert_eq!(rig.driver.rearm(), Some(rmp_base::DisarmCause::LinkLost));
    rig.drive(Twist::new(0.3, 0.0), Duration::from_millis(500));
    assert!(rig.sim.sim().velocity().0 > 0.1);
}

#[test]
fn the_driver_writes_the_stored_limits_and_stops_the_base_when_they_change() {
    let mut rig = Rig::new(1.0);
    // Factory NVM before the driver's start-up: 5.6 times what the robot may do.
    assert_eq!(rig.sim.sim().nvm(NvmFloat::MaxVelocityMps), 2.2352);
    rig.enter_tractor();
    let config = RmpBaseConfig::default();
    for (setting, value) in config.base_settings() {
        assert_eq!(rig.sim.sim().nvm(setting), value, "{setting:?}");
    }
    assert_eq!(rig.sim.sim().nvm(NvmFloat::MaxVelocityMps), 0.5);
    let verified = rig.driver.verified_limits().unwrap();
    assert_eq!(verified.velocity_mps, 0.5);
    // Asking for more than the robot may do: the base runs at the stored 0.5 m/s.
    rig.drive(Twist::new(3.0, 0.0), Duration::from_secs(2));
    assert!((rig.sim.sim().velocity().0 - 0.5).abs() < 1e-6);
    // A service tool raises the stored limit behind the driver's back: the same normalised
    // command would now mean 1.5 m/s. The driver stops the base and names the setting.
    assert!(rig.sim.sim_mut().set_nvm(NvmFloat::MaxVelocityMps, 1.5));
    let mut named = None;
    for _ in 0..5 {
        rig.driver.set_velocity(Twist::new(0.5, 0.0), rig.now);
        if let Err(e) = rig.step() {
            named.get_or_insert(e);
        }
    }
    match named {
        Some(BaseError::LimitChanged {
            setting, reported, ..
        }) => {
            assert_eq!(setting, NvmFloat::MaxVelocityMps);
            assert_eq!(reported, 1.5);
        }
        other => panic!("{other:?}"),
    }
    // Zero commanded since: at rest within 0.5 / 3.923 s, never above the old 0.5 m/s.
    let mut top = 0.0f32;
    for _ in 0..20 {
        rig.driver.set_velocity(Twist::new(0.5, 0.0), rig.now);
        rig.step().ok();
        top = top.max(rig.sim.sim().velocity().0);
    }
    assert!(top <= 0.5 + 1e-6, "{top}");
    assert_eq!(rig.sim.sim().velocity().0, 0.0);
}

#[test]
fn a_safety_stop_brings_the_simulated_base_to_rest_at_the_emergency_deceleration() {
    let bus = MemoryBus::new();
    let sim = SimRmpNode::new(bus.join(), SimRmp::new(SimConfig::default()));
    let config = RmpBaseConfig {
        emergency_decel_mps2: 2.5,
        ..RmpBaseConfig::default()
    };
    let driver = RmpBase::new(CanLink::new(bus.join()), config).unwrap();
    let mut rig = Rig {
        sim,
        driver,
        now: Duration::ZERO,
    };
    rig.enter_tractor();
    assert_eq!(rig.sim.sim().nvm(NvmFloat::MaxDecelerationMps2), 2.5);
    rig.drive(Twist::new(0.5, 0.0), Duration::from_secs(2));
    assert!((rig.sim.sim().velocity().0 - 0.5).abs() < 1e-6);
    rig.driver.safety_stop();
    let stopped_at = rig.now;
    let mut at_rest = None;
    for _ in 0..30 {
        rig.driver.set_velocity(Twist::new(0.5, 0.0), rig.now);
        rig.step().unwrap();
        if at_rest.is_none() && rig.sim.sim().velocity().0 == 0.0 {
            at_rest = Some(rig.now - stopped_at);
        }
    }
    // 0.5 m/s at 2.5 m/s^2: 0.2 s (plus up to two periods of command latency); the comfort
    // 1 m/s^2 would take 0.5 s.
    let at_rest = at_rest.expect("at rest");
    assert!(at_rest <= Duration::from_millis(260), "{at_rest:?}");
    assert!(at_rest >= Duration::from_millis(200), "{at_rest:?}");
}
