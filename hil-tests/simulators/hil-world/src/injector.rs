//! The fault injector (docs/reliability.md): its state over a mission ([`Injector`]) and the
//! world's step that strikes a fault when its trigger comes and keeps up what lasts
//! (`World::inject`). The kinds, triggers and the faulty bus are in [`crate::faults`].

use std::time::Duration;

use can_bus::VirtualCanBus;

use crate::faults::{CanFault, FaultKind, FaultSpec, Trigger};
use crate::report::WorldReport;
use crate::{World, secs};

/// How long the safeguard input stays open (`safeguard-stop`).
const SAFEGUARD_OPEN: Duration = Duration::from_secs(2);

/// The fault injector's state over a mission.
#[derive(Default)]
pub(crate) struct Injector {
    /// When the fault struck.
    pub(crate) at: Option<Duration>,
    /// Base and arm speed at the last step (the triggers).
    pub(crate) base_speed: f64,
    pub(crate) arm_speed: f64,
    /// The gripper is activated (at work on an object), at the last step.
    pub(crate) gripper_active: bool,
    pub(crate) burst_until: Option<Duration>,
    pub(crate) intruder: Option<(VirtualCanBus, Duration)>,
    pub(crate) intruder_next: Duration,
    pub(crate) intruder_frames: u64,
    pub(crate) camera_corrupt_until: Option<Duration>,
    /// The camera's frames cover only the west quarter of the room's frame.
    pub(crate) camera_narrow: bool,
    /// The safeguard input is open until then.
    pub(crate) safeguard_until: Option<Duration>,
    pub(crate) fix_jump: bool,
    pub(crate) jump: Option<()>,
    /// The stops the controller had been asked for when the fault struck.
    pub(crate) stops_at_fault: sim_ur5e::robot::StopsAsked,
    /// The fault is released then (kinds a person releases).
    pub(crate) release_at: Option<Duration>,
    /// Where the base (world x, y) and the arm stood at the release.
    pub(crate) release_pose: Option<([f64; 2], ur5e_kin::Joints)>,
    /// The operator enables then (after a release).
    pub(crate) enable_at: Option<Duration>,
    /// The mission is watched until then (after a release).
    pub(crate) watch_until: Option<Duration>,
}

impl Injector {
    pub(crate) fn take_fix_jump(&mut self) -> bool {
        std::mem::take(&mut self.fix_jump)
    }
}

impl World {
    /// Strikes when `spec`'s trigger comes, and keeps up what lasts (a burst's end, the second
    /// commander's frames).
    #[allow(clippy::too_many_lines, reason = "one arm per fault kind")]
    pub(crate) fn inject(
        &mut self,
        spec: FaultSpec,
        inj: &mut Injector,
        now: Duration,
        start: Duration,
        report: &mut WorldReport,
    ) {
        if inj.at.is_none() {
            let due = match spec.trigger {
                Trigger::Driving => inj.base_speed > 0.3,
                Trigger::ArmMoving => inj.arm_speed > 0.3,
                Trigger::Gripping => inj.arm_speed > 0.3 && inj.gripper_active,
                Trigger::At(t) => now >= start + t,
            };
            if !due {
                return;
            }
            inj.at = Some(now);
            if let Some(rec) = report.fault.as_mut() {
                rec.injected_at_s = Some(secs(now));
                rec.base_speed_then_mps = inj.base_speed;
                rec.arm_speed_then_radps = inj.arm_speed;
            }
            println!(
                "[{:7.2} s] world: injecting {spec} (base {:.2} m/s, arm {:.2} rad/s)",
                secs(now),
                inj.base_speed,
                inj.arm_speed
            );
            inj.stops_at_fault = self.arm.with_robot(|r| r.stops_asked());
            inj.release_at = spec.kind.released_after().map(|d| now + d);
            let bus = self.base.bus_mut();
            bus.mark();
            let links = self.arm.link_faults();
            use std::sync::atomic::Ordering::Relaxed;
            match spec.kind {
                FaultKind::CanLossBurst => {
                    bus.set_fault(CanFault::Loss { p: 1.0 });
                    inj.burst_until = Some(now + Duration::from_millis(400));
                }
                FaultKind::CanLossRandom => bus.set_fault(CanFault::Loss { p: 0.05 }),
                FaultKind::CanDuplicate => bus.set_fault(CanFault::Duplicate),
                FaultKind::CanDelay => bus.set_fault(CanFault::Delay {
                    min: Duration::from_millis(5),
                    max: Duration::from_millis(15),
                }),
                FaultKind::CanReorder => bus.set_fault(CanFault::Reorder),
                FaultKind::CanCorruptFeedback => bus.set_fault(CanFault::CorruptFeedback),
                FaultKind::CanSilent => bus.set_fault(CanFault::Loss { p: 1.0 }),
                FaultKind::BaseFaultWord => self
                    .base
                    .sim_mut()
                    .set_fault(rmp_codec::faults::VELOCITY_CONTROL_FAILED, true),
                FaultKind::KillSwitch => self
                    .base
                    .sim_mut()
                    .set_fault(rmp_codec::faults::KILL_SWITCH_ACTIVE, true),
                FaultKind::SecondCommander => {
                    match VirtualCanBus::join(&self.config.bus_name, "intruder") {
                        Ok(node) => inj.intruder = Some((node, now + Duration::from_millis(200))),
                        Err(e) => log::error!("world: second commander cannot join: {e}"),
                    }
                }
                FaultKind::RtdeDrop => {
                    self.arm.cut_rtde_connections();
                }
                FaultKind::RtdeSilent => links.rtde_muted.store(true, Relaxed),
                FaultKind::ProtectiveStop => self.arm.trigger_protective_stop("fault injection"),
                FaultKind::EmergencyStop => self.arm.trigger_emergency_stop("fault injection"),
                FaultKind::SafeguardStop => {
                    self.arm.set_safeguard_stop(true, "fault injection");
                    inj.safeguard_until = Some(now + SAFEGUARD_OPEN);
                }
                // Overcurrent (Robotiq FLT 0x0E): a major fault, fingers stop.
                FaultKind::GripperFault => self.arm.trigger_gripper_fault(0x0e),
                FaultKind::GripperTimeout => links.gripper_muted.store(true, Relaxed),
                // Replies late since the start; a lost link makes the driver's stop use it.
                FaultKind::DashboardLate => {
                    self.arm.cut_rtde_connections();
                }
                FaultKind::CameraCorrupt => {
                    inj.camera_corrupt_until = Some(now + Duration::from_secs(3));
                }
                FaultKind::ClockJump => inj.jump = Some(()),
                FaultKind::LocalisationJump => inj.fix_jump = true,
                FaultKind::CameraNarrow => inj.camera_narrow = true,
            }
        }
        if inj.release_at.is_some_and(|t| now >= t) {
            inj.release_at = None;
            match spec.kind {
                FaultKind::KillSwitch => self
                    .base
                    .sim_mut()
                    .set_fault(rmp_codec::faults::KILL_SWITCH_ACTIVE, false),
                FaultKind::ProtectiveStop => self.arm.with_robot(|r| r.unlock_protective_stop()),
                FaultKind::EmergencyStop => self.arm.with_robot(|r| r.release_emergency_stop()),
                _ => {}
            }
            let pose = self.base_pose();
            inj.release_pose = Some(([pose.x_m, pose.y_m], self.arm.snapshot().q));
            inj.enable_at = Some(now + Duration::from_millis(500));
            inj.watch_until = Some(now + Duration::from_secs(3));
            if let Some(rec) = report.fault.as_mut() {
                rec.released_at_s = Some(secs(now));
            }
            println!("[{:7.2} s] world: {spec} released", secs(now));
        }
        if inj.safeguard_until.is_some_and(|until| now >= until) {
            inj.safeguard_until = None;
            self.arm.set_safeguard_stop(false, "fault injection over");
        }
        if inj.burst_until.is_some_and(|until| now >= until) {
            inj.burst_until = None;
            self.base.bus_mut().set_fault(CanFault::None);
        }
        if let Some((node, until)) = inj.intruder.as_mut() {
            if now >= *until {
                inj.intruder = None;
            } else if now >= inj.intruder_next {
                inj.intruder_next = now + Duration::from_millis(20);
                // A slow forward crawl: within every limit, but not ours.
                if let Ok(cmd) = rmp_codec::v3::MotionCommand::new(0.05, 0.0) {
                    let raw = cmd.encode();
                    if let Ok(frame) =
                        can_bus::CanFrame::new(can_bus::CanId::Standard(raw.id()), raw.data())
                    {
                        if can_bus::CanBus::send(node, &frame).is_ok() {
                            inj.intruder_frames += 1;
                        }
                    }
                }
            }
        }
    }
}
