//! The two classes of stop (docs/runtime.md, "Safety stops and holds"):
//!
//! - **safety stops latch**: the base ramps to zero, the arm stops, and nothing moves again
//!   without the operator's enable (`operator/enable`) given after the stop. The start of the
//!   executive itself is one (a restarted executive waits for an enable, it does not re-arm on
//!   its own). Most of them end the mission (e-stops, protective stop, a lost link, a base fault
//!   or mode drop, a dead planner, a stall); the UR safeguard stops (the "person nearby" input
//!   of a light curtain or area scanner) pause it: once the arm's safety mode is normal again
//!   and the operator enables, the leg or unload in progress starts over;
//! - **operational holds** resume by themselves when their cause clears (collision monitor,
//!   stale scan, no localisation, a localisation jump, waiting for a plan).
//!
//! This module classifies the UR controller's robot and safety modes.

use std::time::Duration;

use grop_ipc::EventKind;
use motion_control::Twist;

use super::cycle::{ArmCommand, CycleOutputs};
use super::mission::{Latch, MissionCore, Parking, Phase};
use super::unload::{ArmFault, UnloadFailure};
use super::{AbortReason, ArmSnapshot, MissionState};
use ur5e::dashboard::SafetyMode;

/// UR `robot_mode` RUNNING (RTDE, dashboard `robotmode`).
pub const ROBOT_MODE_RUNNING: i32 = 7;

/// What the arm's modes ask of the mission.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArmVerdict {
    /// Go on.
    Normal,
    /// A safeguard stop (or reduced mode where the deployment does not allow it): stop the base
    /// and the arm, latch, go on after the mode is normal again and the operator enables.
    Pause(i32),
    /// A protective or emergency stop: the mission ends.
    Stopped,
    /// Any other safety mode than normal (recovery, violation, fault, ...), or a robot mode
    /// other than running once the arm has run: the mission ends.
    Unsafe {
        /// The safety mode.
        safety_mode: i32,
        /// The robot mode.
        robot_mode: i32,
    },
}

/// Classifies an arm reading. `running_seen`: the arm has reported robot mode RUNNING before
/// (until then, booting and powering modes are expected); `allow_reduced`: the deployment
/// allows the reduced safety limits.
pub fn classify(s: &ArmSnapshot, running_seen: bool, allow_reduced: bool) -> ArmVerdict {
    use SafetyMode as M;
    if s.emergency_stop || s.protective_stop {
        return ArmVerdict::Stopped;
    }
    let verdict = match SafetyMode::from_code(s.safety_mode) {
        // 0: not reported (an arm device or an old log without it): the stop flags decided.
        None if s.safety_mode == 0 => ArmVerdict::Normal,
        Some(M::Normal) => ArmVerdict::Normal,
        Some(M::Reduced) if allow_reduced => ArmVerdict::Normal,
        Some(
            M::Reduced
            | M::SafeguardStop
            | M::AutomaticModeSafeguardStop
            | M::SystemThreePositionEnablingStop,
        ) => ArmVerdict::Pause(s.safety_mode),
        Some(M::ProtectiveStop | M::SystemEmergencyStop | M::RobotEmergencyStop) => {
            ArmVerdict::Stopped
        }
        // Recovery, violation, fault, validate joint id, undefined, and codes UR does not have.
        _ => ArmVerdict::Unsafe {
            safety_mode: s.safety_mode,
            robot_mode: s.robot_mode,
        },
    };
    if verdict == ArmVerdict::Normal && running_seen && s.robot_mode != ROBOT_MODE_RUNNING {
        return ArmVerdict::Unsafe {
            safety_mode: s.safety_mode,
            robot_mode: s.robot_mode,
        };
    }
    verdict
}

/// The name of a safety mode, for events (the dashboard's `safetystatus` name).
pub fn safety_mode_name(code: i32) -> &'static str {
    match SafetyMode::from_code(code) {
        Some(m) => m.name(),
        None if code == 0 => "unreported",
        None => "unknown",
    }
}

impl MissionCore {
    /// Classifies the arm's modes ([`classify`]) and acts on the verdict.
    pub(super) fn arm_modes(
        &mut self,
        snapshot: &ArmSnapshot,
        now: Duration,
        outputs: &mut CycleOutputs,
    ) {
        let verdict = classify(
            snapshot,
            self.arm_running_seen,
            self.config.allow_reduced_mode,
        );
        self.arm_running_seen |= snapshot.robot_mode == ROBOT_MODE_RUNNING;
        self.arm_verdict(verdict, now, outputs);
    }

    /// Acts on what the arm's modes ask (docs/runtime.md, "Safety stops and holds").
    pub(super) fn arm_verdict(
        &mut self,
        verdict: ArmVerdict,
        now: Duration,
        outputs: &mut CycleOutputs,
    ) {
        match verdict {
            ArmVerdict::Normal => {
                if let Some(latch) = self.latch
                    && !latch.cleared
                {
                    self.latch = Some(Latch {
                        cleared: true,
                        ..latch
                    });
                    self.event(
                        EventKind::Enable,
                        now,
                        format_args!(
                            "the arm's safety mode is normal again after {}: waiting for the operator's enable",
                            safety_mode_name(latch.safety_mode)
                        ),
                        outputs,
                    );
                }
            }
            ArmVerdict::Pause(code) => self.latch_pause(code, now, outputs),
            ArmVerdict::Stopped => self.abort(AbortReason::ArmStopped, now, outputs),
            ArmVerdict::Unsafe {
                safety_mode,
                robot_mode,
            } => {
                if !matches!(self.state, MissionState::Aborted(_)) {
                    self.event(
                        EventKind::ArmStopped,
                        now,
                        format_args!(
                            "arm safety mode {safety_mode} ({}), robot mode {robot_mode}: the mission ends",
                            safety_mode_name(safety_mode)
                        ),
                        outputs,
                    );
                }
                self.abort(AbortReason::ArmUnsafe, now, outputs)
            }
        }
    }

    /// A safeguard stop: the base to zero, the arm stopped, the mission paused until the mode
    /// is normal again and the operator enables.
    fn latch_pause(&mut self, code: i32, now: Duration, outputs: &mut CycleOutputs) {
        if matches!(
            self.state,
            MissionState::Aborted(_) | MissionState::Finished
        ) {
            return;
        }
        self.velocity = Twist::ZERO;
        outputs.velocity = Twist::ZERO;
        outputs.safety_stop = true;
        match &mut self.latch {
            Some(latch) => latch.cleared = false,
            None => {
                self.latch = Some(Latch {
                    safety_mode: code,
                    since: now,
                    cleared: false,
                });
                outputs.arm = ArmCommand::Stop;
                self.event(
                    EventKind::ArmStopped,
                    now,
                    format_args!(
                        "{} (safety mode {code}): base to zero, arm stopped; the mission goes on once it clears and the operator enables",
                        safety_mode_name(code)
                    ),
                    outputs,
                );
            }
        }
    }

    /// The operator's enable: arms the base at start; releases a paused mission whose cause
    /// has cleared (the leg or unload in progress starts over).
    pub(super) fn operator_enable(&mut self, now: Duration, outputs: &mut CycleOutputs) {
        if matches!(
            self.state,
            MissionState::Aborted(_) | MissionState::Finished
        ) {
            return;
        }
        if !self.enabled {
            self.enabled = true;
            self.event(
                EventKind::Enable,
                now,
                format_args!("operator enable taken: arming the base"),
                outputs,
            );
            return;
        }
        let Some(latch) = self.latch else { return };
        if !latch.cleared {
            self.event(
                EventKind::Enable,
                now,
                format_args!(
                    "operator enable refused: {} still in force",
                    safety_mode_name(latch.safety_mode)
                ),
                outputs,
            );
            return;
        }
        self.latch = None;
        // The driver's safety stop is released by the same acknowledgement as at start.
        outputs.rearm_base = true;
        match self.phase.take() {
            Some(Phase::Unloading | Phase::PlanningArm { .. }) => {
                // The arm stopped mid-unload: the unload counts as failed and is planned
                // again (GROP+ retries it).
                self.unload = None;
                if let Some(step) = self.current_step() {
                    self.finish_failed_unload(
                        &step,
                        now,
                        UnloadFailure::Arm(ArmFault::SkillFailed),
                        outputs,
                    );
                }
            }
            // Nothing moved in these: they go on.
            Some(phase @ (Phase::Loading { .. } | Phase::AwaitTableFix { .. })) => {
                self.phase = Some(phase)
            }
            // A leg starts over from where the base stands.
            _ => {}
        }
        if matches!(self.parking, Parking::Moving { .. }) {
            self.parking = Parking::NotStarted;
        }
        self.stall_since = None;
        self.monitor_hold_since = None;
        self.event(
            EventKind::Enable,
            now,
            format_args!(
                "operator enable taken after {} ({:.1} s): the mission goes on",
                safety_mode_name(latch.safety_mode),
                now.saturating_sub(latch.since).as_secs_f64()
            ),
            outputs,
        );
    }

    /// The latched safety stop pausing the mission, if one is.
    pub fn latch(&self) -> Option<Latch> {
        self.latch
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn snap(safety: i32, robot: i32) -> ArmSnapshot {
        ArmSnapshot {
            safety_mode: safety,
            robot_mode: robot,
            ..ArmSnapshot::default()
        }
    }

    #[test]
    fn every_safety_mode_but_normal_stops() {
        for code in 0..=14 {
            let v = classify(&snap(code, ROBOT_MODE_RUNNING), true, false);
            let expected = match code {
                0 | 1 => ArmVerdict::Normal,
                2 | 5 | 12 | 13 => ArmVerdict::Pause(code),
                3 | 6 | 7 => ArmVerdict::Stopped,
                _ => ArmVerdict::Unsafe {
                    safety_mode: code,
                    robot_mode: ROBOT_MODE_RUNNING,
                },
            };
            assert_eq!(
                v,
                expected,
                "safety mode {code} ({})",
                safety_mode_name(code)
            );
        }
        assert_eq!(
            classify(&snap(2, ROBOT_MODE_RUNNING), true, true),
            ArmVerdict::Normal,
            "reduced mode where the deployment allows it"
        );
    }

    #[test]
    fn a_robot_mode_other_than_running_stops_once_the_arm_has_run() {
        // Booting (2), power on (4), idle (5): expected before the arm first runs.
        for mode in [2, 4, 5] {
            assert_eq!(classify(&snap(1, mode), false, true), ArmVerdict::Normal);
        }
        // Power off (3), idle (5), backdrive (6) after it ran: the mission ends.
        for mode in [3, 5, 6] {
            assert_eq!(
                classify(&snap(1, mode), true, true),
                ArmVerdict::Unsafe {
                    safety_mode: 1,
                    robot_mode: mode
                }
            );
        }
    }

    #[test]
    fn the_stop_flags_stop_whatever_the_mode_says() {
        let mut s = snap(1, ROBOT_MODE_RUNNING);
        s.protective_stop = true;
        assert_eq!(classify(&s, true, true), ArmVerdict::Stopped);
        let mut s = snap(0, 0);
        s.emergency_stop = true;
        assert_eq!(classify(&s, false, true), ArmVerdict::Stopped);
    }
}
