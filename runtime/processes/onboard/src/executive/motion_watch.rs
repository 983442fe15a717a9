//! The core's watch on motion: the collision monitor's holds (reported, a held turn tried the
//! other way round, a leg held too long failed), stalls (motion sent, none measured), and the
//! docking shape the core asks the monitor for near a standing spot. Part of [`MissionCore`].

use std::time::Duration;

use grop_ipc::EventKind;
use motion_control::Twist;

use super::MissionState;
use super::cycle::{CycleInputs, CycleOutputs, MonitorAction};
use super::mission::{MissionCore, Phase};

/// A hold of the collision monitor is reported once it lasts this long (shorter ones are the
/// approach check easing the base past something).
const HOLD_REPORT_AFTER: Duration = Duration::from_millis(500);

/// A turn in place held this long goes the other way round.
const TURN_FLIP_AFTER: Duration = Duration::from_secs(1);

impl MissionCore {
    /// A turn in place held by the monitor (a chair at the corner that would swing into it) goes
    /// the long way round instead; back to normal once the base drives on or stops turning.
    pub(super) fn turn_the_other_way(&mut self) {
        let Some(sign) = self.forced_turn else {
            return;
        };
        let v = self.velocity;
        if v.speed_mps.abs() < 1e-3 && v.yaw_rate_radps != 0.0 {
            self.velocity.yaw_rate_radps = sign * v.yaw_rate_radps.abs();
        } else {
            self.forced_turn = None;
        }
    }

    /// On the tight stretch next to a standing spot: the straight stretch of a docking, the
    /// back-out (each checked free with the docking shape's margin before it is driven).
    pub(super) fn docking(&self) -> bool {
        let here = self.localiser.estimate();
        let near = |x: f64, y: f64, range: f64| (x - here.x_m).hypot(y - here.y_m) <= range;
        match (&self.phase, self.dock_goal) {
            (Some(Phase::Following { .. }), Some([x, y, range])) => near(x, y, range),
            (
                Some(Phase::Reversing {
                    start, distance_m, ..
                }),
                _,
            ) => near(
                start.x_m,
                start.y_m,
                super::legs::DOCKING_SHAPE_RANGE_M.max(distance_m + 0.05),
            ),
            _ => false,
        }
    }

    /// The collision monitor's holds and stalls: reported when they start and end; a hold that
    /// lasts (an obstacle that does not go away), or a stall (motion sent, none measured: the
    /// base pushes against something), fails the leg, which is then planned again from here.
    #[allow(
        clippy::too_many_lines,
        reason = "the monitor's hold and the stall check, each start and end reported, in order"
    )]
    pub(super) fn watch_motion(&mut self, inputs: &CycleInputs<'_>, outputs: &mut CycleOutputs) {
        let now = inputs.now;
        // Held: the core asks for motion and the monitor lets (almost) none through.
        let asked =
            self.velocity.speed_mps.abs() >= 0.01 || self.velocity.yaw_rate_radps.abs() >= 0.02;
        let let_through =
            inputs.sent.speed_mps.abs() >= 0.02 || inputs.sent.yaw_rate_radps.abs() >= 0.05;
        let holding = (asked && !let_through)
            || matches!(inputs.monitor, MonitorAction::Stop | MonitorAction::Stale)
                && self.monitor_hold_since.is_some();
        match (holding, self.monitor_hold_since) {
            (true, None) => self.monitor_hold_since = Some(now),
            (true, Some(since))
                if self.forced_turn.is_none()
                    && self.velocity.speed_mps.abs() < 1e-3
                    && self.velocity.yaw_rate_radps != 0.0
                    && now.saturating_sub(since) >= TURN_FLIP_AFTER =>
            {
                // A turn in place held: try the other way round (reported), the hold counted
                // afresh.
                self.forced_turn = Some(-self.velocity.yaw_rate_radps.signum());
                self.monitor_hold_since = Some(now);
                self.event(
                    EventKind::Obstacle,
                    now,
                    format_args!("collision monitor: turn held, turning the other way round"),
                    outputs,
                );
            }
            (true, Some(since)) => {
                if !self.hold_reported && now.saturating_sub(since) >= HOLD_REPORT_AFTER {
                    self.hold_reported = true;
                    self.stats.monitor_holds += 1;
                    let why = match inputs.monitor {
                        MonitorAction::Stale => "no fresh scan",
                        MonitorAction::Stop => "an obstacle in the stop zone",
                        _ => "an obstacle ahead",
                    };
                    self.event(
                        EventKind::Obstacle,
                        now,
                        format_args!("collision monitor: base held ({why})"),
                        outputs,
                    );
                }
            }
            (false, Some(since)) => {
                self.monitor_hold_since = None;
                if std::mem::take(&mut self.hold_reported)
                    && matches!(self.state, MissionState::Running)
                {
                    self.event(
                        EventKind::Obstacle,
                        now,
                        format_args!(
                            "collision monitor: clear again after {:.1} s",
                            now.saturating_sub(since).as_secs_f64()
                        ),
                        outputs,
                    );
                }
            }
            (false, None) => {}
        }
        let sent = inputs.sent;
        let measured = inputs.base.odometry;
        // Pushing: a clear command; stalled: a quarter of it or less comes out (a base against
        // a chair creeps by millimetres as its drives slip and catch).
        let (sv, sw) = (f64::from(sent.speed_mps), f64::from(sent.yaw_rate_radps));
        let pushing = sv.abs() >= 0.05 || sw.abs() >= 0.15;
        let still = measured.speed_mps.abs() <= 0.25 * sv.abs() + 0.005
            && measured.yaw_rate_radps.abs() <= 0.25 * sw.abs() + 0.01;
        if pushing && still && inputs.base.driving {
            let since = *self.stall_since.get_or_insert(now);
            if now.saturating_sub(since) >= self.config.stall_after {
                self.stall_since = None;
                self.stats.stalls += 1;
                self.velocity = Twist::ZERO;
                if let Some(step) = self.current_step()
                    && matches!(self.state, MissionState::Running)
                    && self.phase.is_some()
                {
                    self.event(
                        EventKind::Obstacle,
                        now,
                        format_args!(
                            "stall: {:.2} m/s {:.2} rad/s sent, no motion measured for {:.1} s",
                            sent.speed_mps,
                            sent.yaw_rate_radps,
                            self.config.stall_after.as_secs_f64()
                        ),
                        outputs,
                    );
                    self.phase =
                        self.leg_failed(&step, now, "stalled against an obstacle", outputs);
                }
            }
        } else {
            self.stall_since = None;
        }
        if let Some(since) = self.monitor_hold_since {
            let limit = if self.docking() {
                self.config.docking_blocked_timeout
            } else {
                self.config.blocked_timeout
            };
            let leg_running = matches!(
                self.phase,
                Some(Phase::Following { .. } | Phase::Aligning { .. } | Phase::Reversing { .. })
            );
            if leg_running
                && matches!(self.state, MissionState::Running)
                && now.saturating_sub(since) >= limit
                && let Some(step) = self.current_step()
            {
                // Counted again from now: the new leg gets its own time.
                self.monitor_hold_since = Some(now);
                let docking = self.docking();
                let what = if docking {
                    "the standing spot is taken (the scan sees something there)"
                } else {
                    "blocked by an obstacle the scan sees"
                };
                // Held in front of something: the next plan's first leg backs away from it
                // first (as from a table; the request says so), so that its path, planned
                // round what the scan sees, starts where the base can turn.
                self.at_table = !docking;
                self.phase = self.leg_failed(&step, now, what, outputs);
            }
        }
    }
}
