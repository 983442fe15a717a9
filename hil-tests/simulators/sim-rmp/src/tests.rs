//! Protocol and kinematics of the simulated base, driven frame by frame on a simulated clock.

use super::*;
use rmp_codec::v3::MotionCommand;

const MS: Duration = Duration::from_millis(1);

fn motion(v: f32, w: f32) -> RawFrame {
    MotionCommand::new(v, w).unwrap().encode()
}

fn config(c: ConfigCommand) -> RawFrame {
    c.encode(FirmwareProfile::SegwayInc2014).unwrap()
}

/// A base in tractor mode at time 100 ms.
fn tractor_base() -> SimRmp {
    let mut sim = SimRmp::new(SimConfig::default());
    sim.handle_frame(
        &config(ConfigCommand::SetOperationalMode(ModeRequest::Tractor)),
        Duration::ZERO,
    );
    sim.advance(100 * MS);
    assert_eq!(sim.state(), OperationalState::Tractor);
    sim
}

#[test]
fn answers_every_command_with_a_default_feedback_set() {
    let mut sim = SimRmp::new(SimConfig::default());
    let set = sim.handle_frame(&motion(0.0, 0.0), 10 * MS).unwrap();
    assert_eq!(set.frames().count(), 48);
    assert_eq!(set.operational_state(), Some(OperationalState::Standby));
    assert_eq!(set.get(FeedbackItem::SpSwBuildId), Some(SIM_BUILD_ID));
    assert_eq!(set.get_f32(FeedbackItem::VelocityLimit), Some(2.2352));
    // Config NONE is the documented probe: also answered.
    assert!(
        sim.handle_frame(&config(ConfigCommand::None), 20 * MS)
            .is_some()
    );
    // Other traffic (feedback of another base, unrelated ids) is ignored.
    let other = RawFrame::new(0x502, &[0; 8]).unwrap();
    assert!(sim.handle_frame(&other, 30 * MS).is_none());
    assert_eq!(sim.stats().replies, 2);
}

#[test]
fn standby_ignores_motion_and_tractor_follows_it_with_accel_limit() {
    let mut sim = SimRmp::new(SimConfig::default());
    for k in 0..10 {
        sim.handle_frame(&motion(0.5, 0.0), k * 10 * MS);
    }
    assert_eq!(sim.velocity().0, 0.0, "standby must not move");
    let mut sim = tractor_base();
    let mut t = 100 * MS;
    // 0.5 * 2.2352 m/s at 3.923 m/s^2: 1.1176 m/s reached after 0.285 s. A frame acts from
    // its arrival, so ten frames 10 ms apart give 90 ms of acceleration.
    for _ in 0..10 {
        t += 10 * MS;
        sim.handle_frame(&motion(0.5, 0.0), t);
    }
    let expected = 3.923 * 0.09;
    assert!(
        (sim.velocity().0 - expected).abs() < 0.01,
        "{:?}",
        sim.velocity()
    );
    for _ in 0..30 {
        t += 10 * MS;
        sim.handle_frame(&motion(0.5, 0.0), t);
    }
    assert!((sim.velocity().0 - 1.1176).abs() < 1e-4);
}

#[test]
fn loss_of_command_holds_for_half_a_second_then_ramps_at_decel_limit() {
    let mut sim = tractor_base();
    let mut t = 100 * MS;
    for _ in 0..50 {
        t += 10 * MS;
        sim.handle_frame(&motion(0.5, 0.0), t);
    }
    let cruise = sim.velocity().0;
    assert!((cruise - 1.1176).abs() < 1e-4);
    let last = t;
    sim.advance(last + 490 * MS);
    assert_eq!(sim.velocity().0, cruise, "the last command holds for 0.5 s");
    assert!(!sim.command_lost());
    sim.advance(last + 600 * MS);
    assert!(sim.command_lost());
    // About 0.1 s of ramp at the NVM decel limit 3.923 m/s^2 (1 ms physics step).
    let ramped = cruise - sim.velocity().0;
    assert!((ramped - 0.3923).abs() < 0.01, "ramped {ramped}");
    sim.advance(last + 1500 * MS);
    assert_eq!(sim.velocity().0, 0.0);
    assert_eq!(sim.stats().command_losses, 1);
    // A new command revives it.
    sim.handle_frame(&motion(0.2, 0.0), last + 1600 * MS);
    sim.advance(last + 1700 * MS);
    assert!(sim.velocity().0 > 0.0);
}

#[test]
fn stopping_faults_bring_the_base_to_rest_and_block_tractor() {
    let mut sim = tractor_base();
    let mut t = 100 * MS;
    for _ in 0..50 {
        t += 10 * MS;
        sim.handle_frame(&motion(0.3, 0.0), t);
    }
    sim.set_fault(faults::KILL_SWITCH_ACTIVE, true);
    for _ in 0..50 {
        t += 10 * MS;
        let set = sim.handle_frame(&motion(0.3, 0.0), t).unwrap();
        assert!(set.fault_status().unwrap().has(faults::KILL_SWITCH_ACTIVE));
    }
    assert_eq!(sim.velocity().0, 0.0);
    let mut standby = SimRmp::new(SimConfig::default());
    standby.set_fault(faults::KILL_SWITCH_ACTIVE, true);
    standby.handle_frame(
        &config(ConfigCommand::SetOperationalMode(ModeRequest::Tractor)),
        Duration::ZERO,
    );
    standby.advance(200 * MS);
    assert_eq!(standby.state(), OperationalState::Standby);
}

#[test]
fn bad_frames_are_flagged_answered_and_not_keep_alives() {
    // The last valid command was the mode request at t = 0.
    let mut sim = tractor_base();
    let nan = RawFrame::new(0x500, &[0x7F, 0xC0, 0, 0, 0, 0, 0, 0]).unwrap();
    let set = sim.handle_frame(&nan, 450 * MS).unwrap();
    assert!(set.fault_status().unwrap().has(faults::BAD_MOTION_COMMAND));
    let unknown = RawFrame::new(0x501, &[0, 0, 0, 99, 0, 0, 0, 0]).unwrap();
    let set = sim.handle_frame(&unknown, 490 * MS).unwrap();
    assert!(set.fault_status().unwrap().has(faults::UNKNOWN_COMMAND));
    sim.advance(550 * MS);
    assert!(sim.command_lost(), "rejected frames are no keep-alive");
    let set = sim.handle_frame(&motion(0.0, 0.0), 560 * MS).unwrap();
    let f = set.fault_status().unwrap();
    assert!(!f.has(faults::BAD_MOTION_COMMAND));
    assert_eq!(sim.stats().bad_frames, 2);
}

#[test]
fn feedback_bitmaps_and_forced_config_change_the_reply_layout() {
    let mut sim = SimRmp::new(SimConfig::default());
    let small = FeedbackBitmaps::from_items(&[
        FeedbackItem::FaultStatusWord1,
        FeedbackItem::OperationalState,
        FeedbackItem::LinearVelocity,
    ]);
    for (index, bitmap) in small.words().into_iter().enumerate() {
        sim.handle_frame(
            &config(ConfigCommand::SetFeedbackBitmap {
                index: index as u8,
                bitmap,
            }),
            Duration::ZERO,
        );
    }
    let set = sim.handle_frame(&motion(0.0, 0.0), MS).unwrap();
    assert_eq!(set.frames().count(), 2);
    assert_eq!(set.words()[1], 3, "standby");
    sim.handle_frame(
        &config(ConfigCommand::SetFloat(NvmFloat::MaxVelocityMps, 1.5)),
        2 * MS,
    );
    let forced = sim
        .handle_frame(&config(ConfigCommand::ForceConfigFeedback(true)), 3 * MS)
        .unwrap();
    assert_eq!(*forced.layout(), FeedbackLayout::ForcedConfig);
    assert_eq!(forced.get_f32(FeedbackItem::FramVelocityLimit), Some(1.5));
    assert_eq!(
        forced.get(FeedbackItem::UserFeedbackBitmap1),
        Some(small.words()[0])
    );
    // Bitmap 4 has no items: refused and flagged.
    let set = sim
        .handle_frame(
            &config(ConfigCommand::SetFeedbackBitmap {
                index: 3,
                bitmap: 1,
            }),
            4 * MS,
        )
        .unwrap();
    assert_eq!(set.get(FeedbackItem::UserFeedbackBitmap4), Some(0));
}

#[test]
fn turning_in_place_moves_wheels_opposite_and_respects_yaw_sign() {
    for yaw_sign in [1.0, -1.0] {
        let mut sim = SimRmp::new(SimConfig {
            yaw_sign,
            ..SimConfig::default()
        });
        sim.handle_frame(
            &config(ConfigCommand::SetOperationalMode(ModeRequest::Tractor)),
            Duration::ZERO,
        );
        let mut t = 100 * MS;
        sim.advance(t);
        // +0.1 normalised = 0.3 rad/s in the protocol's sense.
        for _ in 0..100 {
            t += 10 * MS;
            sim.handle_frame(&motion(0.0, 0.1), t);
        }
        let p = sim.pose();
        assert!(p.x_m.abs() < 1e-9 && p.y_m.abs() < 1e-9);
        assert!(p.yaw_rad * yaw_sign > 0.25, "{p:?}");
        let set = sim.feedback();
        let reported = set
            .get_f32(FeedbackItem::DifferentialWheelVelocity)
            .unwrap();
        assert!((reported - 0.3).abs() < 1e-5, "protocol sense is preserved");
        let rf = set.get_f32(FeedbackItem::RightFrontPosition).unwrap() as f64;
        let lf = set.get_f32(FeedbackItem::LeftFrontPosition).unwrap() as f64;
        let track = sim.nvm(NvmFloat::TrackWidthM) as f64;
        assert!(((rf - lf) / track - p.yaw_rad).abs() < 1e-4);
    }
}

#[test]
fn power_down_goes_silent() {
    let mut sim = SimRmp::new(SimConfig::default());
    sim.handle_frame(
        &config(ConfigCommand::SetOperationalMode(ModeRequest::PowerDown)),
        Duration::ZERO,
    );
    sim.advance(100 * MS);
    assert!(sim.is_silent());
    assert!(sim.handle_frame(&motion(0.0, 0.0), 110 * MS).is_none());
}

#[test]
fn stored_limits_start_at_factory_survive_a_power_cycle_and_bound_the_speed() {
    let mut sim = SimRmp::new(SimConfig::default());
    // Factory values at power-on, reported in the user feedback and the forced echo.
    assert_eq!(sim.nvm(NvmFloat::MaxVelocityMps), 2.2352);
    let set = sim.handle_frame(&motion(0.0, 0.0), 10 * MS).unwrap();
    assert_eq!(set.get_f32(FeedbackItem::VelocityLimit), Some(2.2352));
    assert_eq!(set.get_f32(FeedbackItem::YawRateLimit), Some(3.0));
    // A host writes the robot's limits.
    for (p, v) in [
        (NvmFloat::MaxVelocityMps, 0.4f32),
        (NvmFloat::MaxTurnRateRadps, 1.0),
        (NvmFloat::MaxAccelerationMps2, 0.5),
    ] {
        sim.handle_frame(&config(ConfigCommand::SetFloat(p, v)), 20 * MS);
    }
    sim.handle_frame(&config(ConfigCommand::ForceConfigFeedback(true)), 30 * MS);
    let echo = sim
        .handle_frame(&config(ConfigCommand::None), 40 * MS)
        .unwrap();
    assert_eq!(echo.get_f32(FeedbackItem::FramVelocityLimit), Some(0.4));
    assert_eq!(echo.get_f32(FeedbackItem::FramYawRateLimit), Some(1.0));
    assert_eq!(echo.get_f32(FeedbackItem::FramAccelLimit), Some(0.5));
    sim.handle_frame(&config(ConfigCommand::ForceConfigFeedback(false)), 50 * MS);
    // Power cycle: F-RAM kept, the rest as at power-on.
    sim.handle_frame(
        &config(ConfigCommand::SetOperationalMode(ModeRequest::Tractor)),
        60 * MS,
    );
    sim.advance(200 * MS);
    assert_eq!(sim.state(), OperationalState::Tractor);
    sim.power_cycle();
    assert_eq!(sim.state(), OperationalState::Standby);
    assert_eq!(sim.nvm(NvmFloat::MaxVelocityMps), 0.4);
    assert!(!matches!(sim.layout(), FeedbackLayout::ForcedConfig));
    let set = sim.handle_frame(&motion(0.0, 0.0), 210 * MS).unwrap();
    assert_eq!(set.get_f32(FeedbackItem::VelocityLimit), Some(0.4));
    assert_eq!(set.get_f32(FeedbackItem::YawRateLimit), Some(1.0));
    // Full command in tractor: the base runs at its stored 0.4 m/s, never faster.
    sim.handle_frame(
        &config(ConfigCommand::SetOperationalMode(ModeRequest::Tractor)),
        220 * MS,
    );
    let mut t = 300 * MS;
    let mut top = 0.0f32;
    for _ in 0..200 {
        sim.handle_frame(&motion(1.0, 1.0), t);
        top = top.max(sim.velocity().0);
        t += 10 * MS;
    }
    assert_eq!(top, 0.4);
    assert!((sim.velocity().1 - 1.0).abs() < 1e-6);
    // Out-of-range writes are refused (by the codec on the bus, by `set_nvm` here).
    assert!(!sim.set_nvm(NvmFloat::MaxVelocityMps, 9.0));
    assert!(sim.set_nvm(NvmFloat::MaxVelocityMps, 0.3));
    assert_eq!(sim.nvm(NvmFloat::MaxVelocityMps), 0.3);
}
