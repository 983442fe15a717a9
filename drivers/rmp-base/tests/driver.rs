//! Driver behaviour against a scripted base on the in-memory bus, on a simulated clock:
//! start-up configuration, modes, limits and normalisation, the input watchdog, base silence,
//! unreadable feedback and faults.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::time::Duration;

use can_bus::{CanBus, MemoryBus, MemoryBusNode};
use motion_control::Twist;
use rmp_base::{
    BaseError, BaseMode, CanLink, DisarmCause, RmpBase, RmpBaseConfig, from_can, to_can,
};
use rmp_codec::faults::{self, FaultStatus};
use rmp_codec::feedback::{FeedbackBitmaps, FeedbackItem, FeedbackLayout, FeedbackSet};
use rmp_codec::v3::{
    ConfigCommand, FirmwareProfile, HostCommand, ModeRequest, MotionCommand, NvmFloat,
    OperationalState,
};

const PERIOD: Duration = Duration::from_millis(20);

/// A base that answers every command with a set in `layout`, from scripted values.
struct ScriptedBase {
    node: MemoryBusNode,
    state: OperationalState,
    accepts_tractor: bool,
    faults: FaultStatus,
    /// Stored float settings (factory values at power-on), in parameter order.
    nvm: [f32; 11],
    /// Stores float settings written to it (a real base does).
    obeys_limits: bool,
    /// Reports this velocity limit instead of the stored one (a base that changed it).
    reported_velocity_limit: Option<f32>,
    /// Reported linear velocity; `None`: what the last motion command asks for (normalised
    /// velocity times the reported limit), as a base that follows its commands.
    speed_override_mps: Option<f32>,
    answering: bool,
    layout: FeedbackLayout,
    /// Applies feedback-bitmap writes to `layout` (a real base does).
    obeys_bitmaps: bool,
    /// Forced configuration feedback on (config command 30).
    forced: bool,
    /// Every motion command received (normalised velocity, yaw).
    motions: Vec<(f32, f32)>,
    configs: Vec<ConfigCommand>,
}

impl ScriptedBase {
    fn new(bus: &MemoryBus) -> Self {
        Self {
            node: bus.join(),
            state: OperationalState::Standby,
            accepts_tractor: true,
            faults: FaultStatus::CLEAR,
            nvm: NvmFloat::ALL.map(NvmFloat::default_value),
            obeys_limits: true,
            reported_velocity_limit: None,
            speed_override_mps: None,
            answering: true,
            layout: FeedbackLayout::default(),
            obeys_bitmaps: true,
            forced: false,
            motions: Vec::new(),
            configs: Vec::new(),
        }
    }

    fn serve(&mut self) {
        while let Some(frame) = self.node.try_recv().unwrap() {
            let raw = from_can(&frame).unwrap();
            match HostCommand::decode(FirmwareProfile::SegwayInc2014, &raw).unwrap() {
                HostCommand::Motion(m) => self.motions.push((m.velocity(), m.yaw_rate())),
                HostCommand::Config(c) => {
                    if let (
                        ConfigCommand::SetFeedbackBitmap { index, bitmap },
                        true,
                        FeedbackLayout::User(b),
                    ) = (c, self.obeys_bitmaps, self.layout)
                    {
                        let mut words = b.words();
                        words[index as usize] = bitmap;
                        self.layout = FeedbackLayout::User(FeedbackBitmaps::new(words).unwrap());
                    }
                    if let ConfigCommand::ForceConfigFeedback(on) = c {
                        self.forced = on;
                    }
                    if let (ConfigCommand::SetFloat(setting, value), true) = (c, self.obeys_limits)
                    {
                        self.nvm[nvm_index(setting)] = value;
                    }
                    if c == ConfigCommand::SetOperationalMode(ModeRequest::Tractor)
                        && self.accepts_tractor
                    {
                        self.state = OperationalState::Tractor;
                    }
                    self.configs.push(c);
                }
            }
            if !self.answering {
                continue;
            }
            let FeedbackLayout::User(bitmaps) = self.layout else {
                unreachable!("the scripted base keeps a user layout")
            };
            let layout = if self.forced {
                FeedbackLayout::ForcedConfig
            } else {
                self.layout
            };
            let velocity_limit = self
                .reported_velocity_limit
                .unwrap_or(self.nvm[nvm_index(NvmFloat::MaxVelocityMps)]);
            let speed_mps = self.speed_override_mps.unwrap_or_else(|| {
                self.motions.last().map_or(0.0, |m| m.0)
                    * self.nvm[nvm_index(NvmFloat::MaxVelocityMps)]
            });
            let nvm = self.nvm;
            let set = FeedbackSet::from_fn(layout, |item| match item {
                _ if (76..87).contains(&(item as usize)) => nvm[item as usize - 76].to_bits(),
                FeedbackItem::UserFeedbackBitmap1 => bitmaps.words()[0],
                FeedbackItem::UserFeedbackBitmap2 => bitmaps.words()[1],
                FeedbackItem::UserFeedbackBitmap3 => bitmaps.words()[2],
                FeedbackItem::UserFeedbackBitmap4 => bitmaps.words()[3],
                FeedbackItem::OperationalState => self.state.to_word(),
                FeedbackItem::FaultStatusWord1 => self.faults.words()[0],
                FeedbackItem::VelocityLimit => velocity_limit.to_bits(),
                FeedbackItem::YawRateLimit => nvm[nvm_index(NvmFloat::MaxTurnRateRadps)].to_bits(),
                FeedbackItem::LinearVelocity => speed_mps.to_bits(),
                _ => 0,
            });
            for f in set.frames() {
                self.node.send(&to_can(&f)).unwrap();
            }
        }
    }
}

fn nvm_index(setting: NvmFloat) -> usize {
    NvmFloat::ALL.iter().position(|p| *p == setting).unwrap()
}

struct Rig {
    bus: MemoryBus,
    base: ScriptedBase,
    driver: RmpBase<CanLink<MemoryBusNode>>,
    now: Duration,
}

impl Rig {
    fn new(config: RmpBaseConfig) -> Self {
        let bus = MemoryBus::new();
        let base = ScriptedBase::new(&bus);
        let driver = RmpBase::new(CanLink::new(bus.join()), config).unwrap();
        Self {
            bus,
            base,
            driver,
            now: Duration::ZERO,
        }
    }

    fn tick(&mut self) -> Result<rmp_base::Tick, BaseError> {
        let r = self.driver.tick(self.now);
        self.base.serve();
        self.now += PERIOD;
        r
    }

    /// Ticks until the driver reports tractor.
    fn enter_tractor(&mut self) {
        self.driver.request_mode(BaseMode::Tractor, self.now);
        for _ in 0..50 {
            if self.tick().unwrap().mode_reached == Some(BaseMode::Tractor) {
                assert!(self.driver.is_driving());
                return;
            }
        }
        panic!("tractor never confirmed");
    }
}

#[test]
fn start_up_writes_every_feedback_bitmap_then_commands_motion() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    for _ in 0..20 {
        rig.tick().unwrap();
    }
    let written: Vec<_> = rig.base.configs[..4].to_vec();
    let expected: Vec<_> = RmpBaseConfig::default()
        .feedback
        .words()
        .iter()
        .enumerate()
        .map(|(i, b)| ConfigCommand::SetFeedbackBitmap {
            index: i as u8,
            bitmap: *b,
        })
        .collect();
    assert_eq!(written, expected);
    // Then what the base holds is read through the forced configuration feedback: its factory
    // limits, so the robot's are written into its stored settings and read back again.
    assert_eq!(
        rig.base.configs[4],
        ConfigCommand::ForceConfigFeedback(true)
    );
    assert_eq!(
        rig.base.configs[5],
        ConfigCommand::ForceConfigFeedback(false)
    );
    let limits: Vec<_> = RmpBaseConfig::default()
        .base_settings()
        .iter()
        .map(|(setting, value)| ConfigCommand::SetFloat(*setting, *value))
        .collect();
    assert_eq!(rig.base.configs[6..12], limits[..]);
    assert_eq!(
        rig.base.configs[6],
        ConfigCommand::SetFloat(NvmFloat::MaxVelocityMps, 0.5)
    );
    assert_eq!(
        rig.base.configs[12],
        ConfigCommand::ForceConfigFeedback(true)
    );
    assert_eq!(
        rig.base.configs[13],
        ConfigCommand::ForceConfigFeedback(false)
    );
    let verified = rig.driver.verified_limits().expect("limits verified");
    assert_eq!((verified.velocity_mps, verified.yaw_rate_radps), (0.5, 1.0));
    assert_eq!(
        rig.base.nvm[nvm_index(NvmFloat::MaxDecelerationMps2)],
        3.923
    );
    assert!(!rig.base.forced);
    assert!(
        !rig.base.motions.is_empty(),
        "keep-alive motion after start-up"
    );
    assert!(rig.base.motions.iter().all(|m| *m == (0.0, 0.0)));
    assert_eq!(rig.driver.status().state, Some(OperationalState::Standby));
}

/// The driver wrote none of the base's stored limits.
fn assert_no_limit_written(rig: &Rig) {
    assert!(
        !rig.base
            .configs
            .iter()
            .any(|c| matches!(c, ConfigCommand::SetFloat(..))),
        "{:?}",
        rig.base.configs
    );
}

#[test]
fn a_base_that_holds_the_limits_already_gets_no_write() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    for (setting, value) in RmpBaseConfig::default().base_settings() {
        rig.base.nvm[nvm_index(setting)] = value;
    }
    for _ in 0..20 {
        rig.tick().unwrap();
    }
    assert_no_limit_written(&rig);
    let verified = rig.driver.verified_limits().expect("limits verified");
    assert_eq!((verified.velocity_mps, verified.yaw_rate_radps), (0.5, 1.0));
}

#[test]
fn a_replay_of_an_older_driver_adopts_the_stored_limits_and_writes_none() {
    let mut rig = Rig::new(RmpBaseConfig {
        adopt_stored_limits: true,
        ..RmpBaseConfig::default()
    });
    for _ in 0..20 {
        rig.tick().unwrap();
    }
    assert_no_limit_written(&rig);
    // The factory limits, as the base holds them.
    let verified = rig.driver.verified_limits().expect("limits adopted");
    assert_eq!(
        (verified.velocity_mps, verified.yaw_rate_radps),
        (
            NvmFloat::MaxVelocityMps.default_value(),
            NvmFloat::MaxTurnRateRadps.default_value()
        )
    );
}

#[test]
fn velocity_is_limited_and_normalised_by_the_reported_limit() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.enter_tractor();
    let mut last = 0.0;
    for _ in 0..100 {
        rig.driver.set_velocity(Twist::new(3.0, 0.0), rig.now);
        let tick = rig.tick().unwrap();
        assert!(!tick.input_stale);
        // Accel limit 0.5 m/s^2 at 20 ms: at most 0.01 m/s more per tick.
        assert!(tick.commanded.speed_mps - last <= 0.01 + 1e-6);
        last = tick.commanded.speed_mps;
    }
    // Clamped to the driver's 0.5 m/s, sent as 0.5 / 0.5: the base's stored limit, which the
    // driver wrote and read back (not its factory 2.2352).
    assert_eq!(last, 0.5);
    let (v, _) = *rig.base.motions.last().unwrap();
    assert_eq!(v, 1.0);
    // Normalised by the verified value all along: every command is commanded / 0.5.
    assert!(rig.base.motions.iter().all(|m| m.0 <= 1.0));
}

#[test]
fn stale_input_ramps_the_command_to_zero() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.enter_tractor();
    for _ in 0..60 {
        rig.driver.set_velocity(Twist::new(0.4, 0.5), rig.now);
        rig.tick().unwrap();
    }
    let fed_at = rig.now - PERIOD;
    let mut stale_seen_at = None;
    for _ in 0..40 {
        let t = rig.tick().unwrap();
        if t.input_stale && stale_seen_at.is_none() {
            stale_seen_at = Some(rig.now - PERIOD);
        }
    }
    let stale_at = stale_seen_at.expect("the input watchdog fired");
    // Default input timeout 100 ms: stale on the first tick more than 100 ms after the feed.
    assert!(stale_at - fed_at > Duration::from_millis(100));
    assert!(stale_at - fed_at <= Duration::from_millis(120));
    // 0.4 m/s at 1 m/s^2 decel: zero within 0.4 s; the base receives zeros at the end.
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    // And the ramp was a ramp, not a jump: some command between 0 and 0.2 (0.4 / 2.0) was sent.
    assert!(rig.base.motions.iter().any(|m| m.0 > 0.0 && m.0 < 0.19));
}

#[test]
fn a_silent_base_is_an_error_and_gets_zero_commands() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.enter_tractor();
    for _ in 0..30 {
        rig.driver.set_velocity(Twist::new(0.4, 0.0), rig.now);
        rig.tick().unwrap();
    }
    rig.base.answering = false;
    let silent_since = rig.now;
    let mut error_at = None;
    for _ in 0..30 {
        rig.driver.set_velocity(Twist::new(0.4, 0.0), rig.now);
        match rig.tick() {
            Ok(_) => {}
            Err(BaseError::Silent {
                silent_for,
                timeout,
            }) => {
                assert!(silent_for > timeout);
                error_at.get_or_insert(rig.now - PERIOD);
            }
            Err(other) => panic!("unexpected {other}"),
        }
    }
    let error_at = error_at.expect("silence must be reported");
    assert!(error_at - silent_since <= Duration::from_millis(300));
    // Fresh inputs notwithstanding, the driver now sends zero.
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    // When the base answers again the driver reports no error, but the link was lost: it
    // stays disarmed, commanding zero, until it is re-armed.
    rig.base.answering = true;
    rig.tick().ok();
    assert_eq!(rig.driver.disarmed(), Some(DisarmCause::LinkLost));
    for _ in 0..10 {
        rig.driver.set_velocity(Twist::new(0.4, 0.0), rig.now);
        let tick = rig.tick().unwrap();
        assert!(!tick.armed);
        assert_eq!(tick.commanded, Twist::ZERO);
    }
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    assert_eq!(rig.driver.rearm(), Some(DisarmCause::LinkLost));
    for _ in 0..10 {
        rig.driver.set_velocity(Twist::new(0.4, 0.0), rig.now);
        assert!(rig.tick().unwrap().armed);
    }
    assert!(
        rig.base.motions.last().unwrap().0 > 0.0,
        "moves again after the re-arm"
    );
}

#[test]
fn a_later_report_of_another_limit_disarms_until_rearmed() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.enter_tractor();
    for _ in 0..30 {
        rig.driver.set_velocity(Twist::new(0.2, 0.0), rig.now);
        rig.tick().unwrap();
    }
    assert!((rig.base.motions.last().unwrap().0 - 0.4).abs() < 1e-6);
    // Someone resets the base's settings (a service tool): it now reports 0.45 m/s. Normalised
    // commands would mean other speeds.
    rig.base.reported_velocity_limit = Some(0.45);
    let mut got = None;
    for _ in 0..3 {
        rig.driver.set_velocity(Twist::new(0.2, 0.0), rig.now);
        if let Err(e) = rig.tick() {
            got = Some(e);
            break;
        }
    }
    match got {
        Some(BaseError::LimitChanged {
            setting,
            verified,
            reported,
        }) => {
            assert_eq!(setting, NvmFloat::MaxVelocityMps);
            assert_eq!((verified, reported), (0.5, 0.45));
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        rig.driver.disarmed(),
        Some(DisarmCause::LimitChanged { .. })
    ));
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    // A re-arm while the report still differs disarms again on the next tick.
    rig.driver.rearm();
    rig.driver.set_velocity(Twist::new(0.2, 0.0), rig.now);
    assert!(matches!(rig.tick(), Err(BaseError::LimitChanged { .. })));
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    // Reported as verified again, and re-armed: it drives.
    rig.base.reported_velocity_limit = None;
    rig.tick().ok();
    rig.driver.rearm();
    for _ in 0..10 {
        rig.driver.set_velocity(Twist::new(0.2, 0.0), rig.now);
        rig.tick().unwrap();
    }
    assert!(rig.base.motions.last().unwrap().0 > 0.0);
}

#[test]
fn a_base_that_does_not_take_the_limits_is_never_driven() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.base.obeys_limits = false; // keeps its factory 2.2352 m/s
    let mut got = None;
    rig.driver.request_mode(BaseMode::Tractor, rig.now);
    for _ in 0..100 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        if let Err(e) = rig.tick() {
            got.get_or_insert(e);
        }
    }
    let e = got.expect("the refusal is reported");
    match &e {
        BaseError::LimitNotTaken {
            setting,
            written,
            read,
        } => {
            assert_eq!(*setting, NvmFloat::MaxVelocityMps);
            assert_eq!(*written, 0.5);
            assert_eq!(*read, Some(2.2352));
        }
        other => panic!("{other:?}"),
    }
    let text = e.to_string();
    assert!(
        text.contains("MaxVelocityMps") && text.contains("0.5") && text.contains("2.2352"),
        "{text}"
    );
    // Written and verified three times over before it gave up.
    let velocity_writes = rig
        .base
        .configs
        .iter()
        .filter(|c| matches!(c, ConfigCommand::SetFloat(NvmFloat::MaxVelocityMps, _)))
        .count();
    assert_eq!(velocity_writes, 3);
    assert!(rig.driver.verified_limits().is_none());
    assert_eq!(rig.base.state, OperationalState::Tractor);
    assert!(rig.base.motions.iter().all(|m| *m == (0.0, 0.0)));
    // No re-arm helps: the refusal holds for the driver's life.
    rig.driver.rearm();
    for _ in 0..10 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        assert!(matches!(rig.tick(), Err(BaseError::LimitNotTaken { .. })));
    }
    assert!(rig.base.motions.iter().all(|m| *m == (0.0, 0.0)));
}

#[test]
fn a_safety_stop_ramps_at_the_emergency_deceleration_until_rearmed() {
    let config = RmpBaseConfig {
        emergency_decel_mps2: 2.5,
        ..RmpBaseConfig::default()
    };
    let mut rig = Rig::new(config);
    rig.enter_tractor();
    for _ in 0..60 {
        rig.driver.set_velocity(Twist::new(0.5, 0.5), rig.now);
        rig.tick().unwrap();
    }
    rig.driver.safety_stop();
    assert!(rig.driver.safety_stopping());
    let mut speeds = vec![0.5f32];
    let mut yaws = vec![0.5f32];
    for _ in 0..15 {
        // Fresh inputs asking for speed change nothing.
        rig.driver.set_velocity(Twist::new(0.5, 0.5), rig.now);
        let t = rig.tick().unwrap();
        speeds.push(t.commanded.speed_mps);
        yaws.push(t.commanded.yaw_rate_radps);
    }
    // 2.5 m/s^2 at 20 ms: 0.05 m/s less per tick (the comfort ramp, 1 m/s^2, would be 0.02),
    // zero after 10 ticks, and it stays zero.
    for (i, pair) in speeds.windows(2).enumerate() {
        let step = pair[0] - pair[1];
        if pair[0] > 0.0 {
            assert!((step - 0.05).abs() < 1e-5, "tick {i}: {speeds:?}");
        } else {
            assert_eq!(pair[1], 0.0);
        }
    }
    assert_eq!(speeds[10], 0.0, "{speeds:?}");
    // The frames on the bus say the same: normalised by the verified 0.5 m/s.
    let sent: Vec<f32> = rig.base.motions[rig.base.motions.len() - 15..]
        .iter()
        .map(|m| m.0 * 0.5)
        .collect();
    for (frame, commanded) in sent.iter().zip(&speeds[1..]) {
        assert!((frame - commanded).abs() < 1e-6, "{sent:?} {speeds:?}");
    }
    // Yaw at the yaw-acceleration limit (2 rad/s^2: 0.04 rad/s per tick).
    assert!((yaws[0] - yaws[1] - 0.04).abs() < 1e-5, "{yaws:?}");
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    // Latched until the re-arm, then the comfort ramp up.
    rig.driver.rearm();
    assert!(!rig.driver.safety_stopping());
    rig.driver.set_velocity(Twist::new(0.5, 0.0), rig.now);
    let t = rig.tick().unwrap();
    assert!((t.commanded.speed_mps - 0.01).abs() < 1e-6);
}

#[test]
fn a_base_faster_than_commanded_is_stopped_until_rearmed() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.enter_tractor();
    for _ in 0..40 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        rig.tick().unwrap();
    }
    // The base runs away: 1 m/s measured against 0.3 commanded.
    rig.base.speed_override_mps = Some(1.0);
    let mut tripped = None;
    for _ in 0..5 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        if let Err(e) = rig.tick() {
            tripped = Some(e);
            break;
        }
    }
    match tripped {
        Some(BaseError::Overspeed {
            measured_mps,
            allowed_mps,
            ..
        }) => {
            assert_eq!(measured_mps, 1.0);
            assert!(allowed_mps < 0.5, "{allowed_mps}");
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        rig.driver.disarmed(),
        Some(DisarmCause::Overspeed { .. })
    ));
    // Zero from the tick it tripped on, reported every tick until re-armed, even once the base
    // behaves again.
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    rig.base.speed_override_mps = None;
    for _ in 0..10 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        assert!(matches!(rig.tick(), Err(BaseError::Overspeed { .. })));
        assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    }
    rig.driver.rearm();
    for _ in 0..10 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        rig.tick().unwrap();
    }
    assert!(rig.base.motions.last().unwrap().0 > 0.0);
}

#[test]
fn a_second_commander_on_the_bus_stops_the_base_until_rearmed() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.enter_tractor();
    for _ in 0..20 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        rig.tick().unwrap();
    }
    // Our own motion frames never come back to us: nothing tripped so far.
    assert!(rig.driver.disarmed().is_none());
    // Another host (a teleop node left running, a second driver) commands the base.
    let mut intruder = rig.bus.join();
    let frame = to_can(&MotionCommand::new(0.5, 0.0).unwrap().encode());
    intruder.send(&frame).unwrap();
    rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
    match rig.tick() {
        Err(BaseError::SecondCommander { frames, last_id }) => {
            assert_eq!((frames, last_id), (1, 0x500));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(rig.driver.disarmed(), Some(DisarmCause::SecondCommander));
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    // Latched: zero, and reported, every tick after, though the other host went quiet.
    for _ in 0..10 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        assert!(matches!(rig.tick(), Err(BaseError::SecondCommander { .. })));
        assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    }
    rig.driver.rearm();
    for _ in 0..10 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        rig.tick().unwrap();
    }
    assert!(rig.base.motions.last().unwrap().0 > 0.0);
}

#[test]
fn a_stalled_control_loop_counts_as_a_lost_link() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.enter_tractor();
    for _ in 0..20 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        rig.tick().unwrap();
    }
    // Our loop stops for 400 ms (longer than the base's patience); feedback sent before the
    // stall is still queued, so the base does not look silent.
    rig.now += Duration::from_millis(400);
    rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
    assert!(matches!(rig.tick(), Err(BaseError::Silent { .. })));
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    assert_eq!(rig.driver.disarmed(), Some(DisarmCause::LinkLost));
}

#[test]
fn a_fault_disarms_until_rearmed_even_after_it_clears() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.enter_tractor();
    rig.base.faults.set(faults::KILL_SWITCH_ACTIVE);
    // The fault arrives with the reply to this tick's command.
    rig.tick().unwrap();
    for _ in 0..5 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        assert!(matches!(rig.tick(), Err(BaseError::Faulted { .. })));
    }
    rig.base.faults = FaultStatus::CLEAR;
    rig.tick().ok();
    for _ in 0..10 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        assert!(!rig.tick().unwrap().armed);
    }
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
    assert!(matches!(
        rig.driver.rearm(),
        Some(DisarmCause::Faulted { .. })
    ));
    for _ in 0..10 {
        rig.driver.set_velocity(Twist::new(0.3, 0.0), rig.now);
        rig.tick().unwrap();
    }
    assert!(rig.base.motions.last().unwrap().0 > 0.0);
}

#[test]
fn a_base_that_never_answers_is_reported() {
    let mut rig = Rig::new(RmpBaseConfig {
        assume_feedback_configured: true,
        ..RmpBaseConfig::default()
    });
    rig.base.answering = false;
    let errors: Vec<_> = (0..20).map(|_| rig.tick()).collect();
    assert!(errors[..12].iter().all(|r| r.is_ok()));
    let last = errors.last().unwrap();
    assert!(matches!(last, Err(BaseError::Silent { .. })), "{last:?}");
    assert!(
        last.as_ref()
            .unwrap_err()
            .to_string()
            .contains("not answering")
    );
}

#[test]
fn a_mode_the_base_refuses_times_out() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.base.accepts_tractor = false;
    // Start-up (bitmaps, limits, read-back) first.
    for _ in 0..15 {
        rig.tick().unwrap();
    }
    rig.driver.request_mode(BaseMode::Tractor, rig.now);
    let mut timed_out = false;
    for _ in 0..150 {
        rig.driver.set_velocity(Twist::new(0.4, 0.0), rig.now);
        match rig.tick() {
            Ok(t) => assert_eq!(t.commanded, Twist::ZERO, "no motion outside tractor"),
            Err(BaseError::ModeTimeout {
                wanted, reported, ..
            }) => {
                assert_eq!(wanted, BaseMode::Tractor);
                assert_eq!(reported, Some(OperationalState::Standby));
                timed_out = true;
                break;
            }
            Err(e) => panic!("{e}"),
        }
    }
    assert!(timed_out);
    let requests = rig
        .base
        .configs
        .iter()
        .filter(|c| **c == ConfigCommand::SetOperationalMode(ModeRequest::Tractor))
        .count();
    // Resent every 100 ms for 2 s.
    assert!((19..=22).contains(&requests), "{requests}");
}

#[test]
fn a_base_that_keeps_other_bitmaps_is_reported_at_start_up() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.base.obeys_bitmaps = false;
    let mut got = None;
    for _ in 0..40 {
        if let Err(e) = rig.tick() {
            got = Some(e);
            break;
        }
    }
    match got {
        Some(BaseError::FeedbackConfigRejected {
            wanted,
            echoed,
            attempts,
        }) => {
            assert_eq!(wanted, RmpBaseConfig::default().feedback.words());
            assert_eq!(echoed, FeedbackBitmaps::DEFAULT.words());
            assert_eq!(attempts, 3);
        }
        other => panic!("{other:?}"),
    }
    assert!(!rig.driver.is_driving());
}

#[test]
fn a_layout_changed_behind_the_drivers_back_is_unreadable_not_misread() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.enter_tractor();
    rig.driver.set_velocity(Twist::new(0.2, 0.0), rig.now);
    rig.tick().unwrap();
    // Someone else (a service tool) restores the factory bitmaps: 48 frames per reply, whose
    // first 8 would "complete" a set of the wrong items.
    rig.base.layout = FeedbackLayout::default();
    // The reply to the last command before the change is still valid: take it first.
    rig.tick().unwrap();
    let sets_before = rig.driver.status().feedback_sets;
    let mut got = None;
    for _ in 0..30 {
        rig.driver.set_velocity(Twist::new(0.2, 0.0), rig.now);
        if let Err(e) = rig.tick() {
            got = Some(e);
        }
    }
    assert_eq!(
        rig.driver.status().feedback_sets,
        sets_before,
        "no wrong set taken"
    );
    match got {
        Some(BaseError::FeedbackUnreadable {
            expected_frames,
            last_error,
            ..
        }) => {
            assert_eq!(expected_frames, 8);
            assert!(last_error.is_some());
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
}

#[test]
fn a_faulted_base_gets_zero_and_the_fault_is_named() {
    let mut rig = Rig::new(RmpBaseConfig::default());
    rig.enter_tractor();
    for _ in 0..30 {
        rig.driver.set_velocity(Twist::new(0.4, 0.0), rig.now);
        rig.tick().unwrap();
    }
    rig.base.faults.set(faults::KILL_SWITCH_ACTIVE);
    let mut message = String::new();
    for _ in 0..5 {
        rig.driver.set_velocity(Twist::new(0.4, 0.0), rig.now);
        if let Err(e) = rig.tick() {
            assert!(matches!(e, BaseError::Faulted { .. }));
            message = e.to_string();
        }
    }
    assert!(message.contains("kill switch active"), "{message}");
    assert_eq!(rig.base.motions.last(), Some(&(0.0, 0.0)));
}

#[test]
fn bad_configurations_are_refused_with_the_field_named() {
    let bus = MemoryBus::new();
    let bad_sign = RmpBaseConfig {
        yaw_sign: 0.5,
        ..RmpBaseConfig::default()
    };
    assert!(RmpBase::new(CanLink::new(bus.join()), bad_sign).is_err());
    let no_state = RmpBaseConfig {
        feedback: FeedbackBitmaps::from_items(&[FeedbackItem::LinearVelocity]),
        ..RmpBaseConfig::default()
    };
    let err = RmpBase::new(CanLink::new(bus.join()), no_state)
        .err()
        .unwrap();
    assert!(err.to_string().contains("OperationalState"), "{err}");
    let zero = RmpBaseConfig {
        input_timeout: Duration::ZERO,
        ..RmpBaseConfig::default()
    };
    let err = RmpBase::new(CanLink::new(bus.join()), zero).err().unwrap();
    assert!(err.to_string().contains("input_timeout"));
    let older = RmpBaseConfig {
        profile: FirmwareProfile::Older440,
        feedback: FeedbackBitmaps::new([u32::MAX, 0, 0, 0]).unwrap(),
        ..RmpBaseConfig::default()
    };
    assert!(RmpBase::new(CanLink::new(bus.join()), older).is_ok());
    let soft_stop = RmpBaseConfig {
        emergency_decel_mps2: 0.5, // below the 1.0 comfort deceleration
        ..RmpBaseConfig::default()
    };
    let err = RmpBase::new(CanLink::new(bus.join()), soft_stop)
        .err()
        .unwrap();
    assert!(err.to_string().contains("emergency_decel_mps2"), "{err}");
    let too_hard = RmpBaseConfig {
        emergency_decel_mps2: 9.0,
        ..RmpBaseConfig::default()
    };
    let err = RmpBase::new(CanLink::new(bus.join()), too_hard)
        .err()
        .unwrap();
    assert!(err.to_string().contains("MaxDecelerationMps2"), "{err}");
    let mut fast = RmpBaseConfig::default();
    fast.limits.max_forward_mps = 9.0;
    let err = RmpBase::new(CanLink::new(bus.join()), fast).err().unwrap();
    assert!(err.to_string().contains("MaxVelocityMps"), "{err}");
}
