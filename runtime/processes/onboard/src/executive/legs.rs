//! The legs of a mission: back out from the table, ask for the path, follow it, turn to the
//! goal heading, settle, and dock straight in at a table goal. Part of [`MissionCore`]: each
//! phase reads the cycle's inputs and writes the velocity and worker jobs into its outputs.
//!
//! How far to back out, where to dock and from how far are the plan's (`TaskStep::back_out_m`,
//! `approach_m`: the planner works them out on the map, `crate::docking`); the executive
//! follows them and moves a docking goal only because of what its range sensor shows.

use std::time::Duration;

use grop_ipc::{EventKind, ReplanReason, TaskStep, TaskStepKind};
use motion_control::Twist;
use motion_control::follower::FollowStep;
use planar::{Pose2, wrap_angle};

use super::AbortReason;
use super::cycle::{CycleInputs, CycleOutputs};
use super::mission::{MissionCore, Phase};
use super::worker::{Answer, Job, PathFailure, SeenPoints};
use crate::docking::{DOCK_SHIFTS_M, DOCKING_LINE_MARGIN_M};

/// Legs that may fail in a row before the mission is given up.
pub const MAX_FAILED_LEGS: u32 = 3;

/// Backing-out speed from the table, m/s.
pub const REVERSE_SPEED_MPS: f32 = 0.15;

/// At least the last this many metres to a docking goal (and the first ones backing out) use
/// the collision monitor's docking shape at crawl speed; a longer straight stretch, checked
/// free with [`DOCKING_LINE_MARGIN_M`], uses it all the way.
pub const DOCKING_SHAPE_RANGE_M: f64 = 0.5;

/// How often a blocked way in to a standing spot is looked at again while the base waits.
const DOCK_RECHECK: Duration = Duration::from_millis(200);

/// How long the worker may take for a path.
const PATH_ANSWER_TIMEOUT: Duration = Duration::from_secs(5);

impl MissionCore {
    /// Advances the leg of `step` by one base cycle from `phase` (`None`: the leg starts).
    #[allow(
        clippy::too_many_lines,
        reason = "the leg's phases (path, follow, align, settle, dock, back out) as one state machine"
    )]
    pub(super) fn leg(
        &mut self,
        step: &TaskStep,
        pose: Pose2,
        phase: Option<Phase>,
        inputs: &CycleInputs<'_>,
        outputs: &mut CycleOutputs,
    ) -> Option<Phase> {
        let now = inputs.now;
        match phase {
            None => self.start_leg(step, pose, now, outputs),
            Some(Phase::PathRequested { id, since }) => match inputs.answer {
                Some(Answer::Path(answer_id, Ok(points))) if *answer_id == id => {
                    match self.follower.set_path(points) {
                        Ok(()) => Some(Phase::Following {
                            deadline: self.leg_deadline(step, pose, now),
                        }),
                        Err(_) => {
                            self.leg_failed(step, now, "path refused by the follower", outputs)
                        }
                    }
                }
                Some(Answer::Path(answer_id, Err(e))) if *answer_id == id => {
                    let why = match e {
                        PathFailure::NoRoute => "no route on the map",
                        PathFailure::WorkerGone => "planning worker gone",
                    };
                    self.leg_failed(step, now, why, outputs)
                }
                _ if now.saturating_sub(since) > PATH_ANSWER_TIMEOUT => {
                    self.leg_failed(step, now, "no path within 5 s", outputs)
                }
                _ => Some(Phase::PathRequested { id, since }),
            },
            Some(Phase::Reversing {
                start,
                distance_m,
                deadline,
            }) => {
                // Backed out far enough, or blocked behind past the deadline: plan from here.
                if pose.distance_m(&start) >= distance_m || now > deadline {
                    self.request_path(step, pose, now, outputs)
                } else {
                    self.velocity = Twist::new(-REVERSE_SPEED_MPS, 0.0);
                    Some(Phase::Reversing {
                        start,
                        distance_m,
                        deadline,
                    })
                }
            }
            Some(Phase::Following { deadline }) => {
                let p = pose.to_f32();
                if now > deadline {
                    self.leg_failed(step, now, "leg took too long (blocked?)", outputs)
                } else {
                    match self.follower.step(&p) {
                        FollowStep::Drive(t) => {
                            self.velocity = t;
                            Some(Phase::Following { deadline })
                        }
                        FollowStep::Arrived | FollowStep::NoPath => {
                            Some(Phase::Aligning { deadline })
                        }
                    }
                }
            }
            Some(Phase::Aligning { deadline }) => {
                let err = wrap_angle(step.yaw_rad - pose.yaw_rad);
                if err.abs() <= self.config.yaw_tolerance_rad {
                    Some(Phase::Settling {
                        until: now + self.config.settle,
                    })
                } else if now > deadline {
                    self.leg_failed(step, now, "could not turn to the goal heading", outputs)
                } else {
                    let max_w = self.config.robot.yaw_rate_radps;
                    let w = (self.config.align_gain * err).clamp(-max_w, max_w);
                    // A floor so the last degrees do not take forever against the limiter.
                    let w = if w.abs() < 0.05 {
                        0.05_f64.copysign(err)
                    } else {
                        w
                    };
                    self.velocity = Twist::new(0.0, w as f32);
                    Some(Phase::Aligning { deadline })
                }
            }
            Some(Phase::Settling { until }) if now < until => Some(Phase::Settling { until }),
            Some(Phase::Settling { .. }) => match self.dock.take() {
                Some(goal) => {
                    // At the pre-goal, facing the table: what the sensor sees now decides
                    // whether (and where, within a few centimetres) to drive straight in.
                    let Some((gx, gy)) = self.docking_goal_in_the_scan(pose, goal, inputs, outputs)
                    else {
                        // Blocked: an operational hold first (someone may pull the chair
                        // away), the leg failed if it lasts.
                        let since = *self.dock_blocked_since.get_or_insert(now);
                        if now.saturating_sub(since) < self.config.docking_blocked_timeout {
                            if since == now {
                                self.event(
                                    EventKind::Obstacle,
                                    now,
                                    format_args!(
                                        "the way in to the standing spot is blocked (the scan sees something): waiting"
                                    ),
                                    outputs,
                                );
                            }
                            self.dock = Some(goal);
                            return Some(Phase::Settling {
                                until: now + DOCK_RECHECK,
                            });
                        }
                        self.dock_blocked_since = None;
                        return self.leg_failed(
                            step,
                            now,
                            "the standing spot is taken (the scan sees something on the way in)",
                            outputs,
                        );
                    };
                    self.dock_blocked_since = None;
                    match self
                        .follower
                        .set_line([pose.x_m as f32, pose.y_m as f32], [gx as f32, gy as f32])
                    {
                        Ok(()) => {
                            // The stretch was checked free with the docking shape's margin:
                            // the monitor uses that shape on all of it (and on at least the
                            // last DOCKING_SHAPE_RANGE_M).
                            let range = (goal[3] + 0.05).max(DOCKING_SHAPE_RANGE_M);
                            self.dock_goal = Some([gx, gy, range]);
                            Some(Phase::Following {
                                deadline: self.leg_deadline(step, pose, now),
                            })
                        }
                        Err(_) => self.leg_failed(step, now, "docking path refused", outputs),
                    }
                }
                None => {
                    self.failed_legs = 0;
                    self.dock_goal = None;
                    let err = pose.distance_m(&Pose2::new(step.x_m, step.y_m, 0.0));
                    self.event(
                        EventKind::GoalReached,
                        now,
                        format_args!(
                            "at ({:.3}, {:.3}) believed, {:.3} m from goal",
                            pose.x_m, pose.y_m, err
                        ),
                        outputs,
                    );
                    self.next_step(now, outputs);
                    None
                }
            },
            // Not a leg phase: the caller handles it.
            Some(other) => Some(other),
        }
    }

    /// Starts a leg: back straight out first as far as the plan says (from a table: turning in
    /// place next to it would sweep the footprint into it), then ask for the path (to the
    /// pre-goal in front of a docked goal, see [`Self::request_path`]).
    fn start_leg(
        &mut self,
        step: &TaskStep,
        pose: Pose2,
        now: Duration,
        outputs: &mut CycleOutputs,
    ) -> Option<Phase> {
        self.at_table = false;
        let distance_m = step.back_out_m;
        if distance_m > 0.0 {
            return Some(Phase::Reversing {
                start: pose,
                distance_m,
                // The plan's distance is checked (at most `MAX_DOCKING_M`): the time fits.
                deadline: now
                    + Duration::try_from_secs_f64(3.0 * distance_m / f64::from(REVERSE_SPEED_MPS))
                        .unwrap_or(Duration::from_secs(60)),
            });
        }
        self.request_path(step, pose, now, outputs)
    }

    /// Asks the worker for the leg's path. A docked goal (`approach_m` > 0: an unload's, or
    /// the loading station's) gets a path to its pre-goal straight behind the goal (facing the
    /// table), where the base turns, then drives straight in, so it never turns next to the
    /// table or between chairs.
    fn request_path(
        &mut self,
        step: &TaskStep,
        pose: Pose2,
        now: Duration,
        outputs: &mut CycleOutputs,
    ) -> Option<Phase> {
        let id = self.next_job_id;
        self.next_job_id += 1;
        self.dock_goal = None;
        let mut to = (step.x_m, step.y_m);
        self.dock = None;
        if step.approach_m < 0.0 {
            // No straight way in: the standing spot itself is not free on the map (the learned
            // feasibility is no geometric check). Driving there and turning would push the
            // base into the furniture; the leg fails before it starts.
            return self.leg_failed(
                step,
                now,
                "no straight way in to the standing spot",
                outputs,
            );
        }
        if step.approach_m > 0.0 {
            let d = step.approach_m;
            let (s, c) = step.yaw_rad.sin_cos();
            to = (step.x_m - c * d, step.y_m - s * d);
            self.dock = Some([step.x_m, step.y_m, step.yaw_rad, d]);
        }
        outputs.job = Some(Job::Path {
            id,
            from: (pose.x_m, pose.y_m),
            from_yaw: pose.yaw_rad,
            to,
            // The shell adds what the range sensor sees.
            seen: SeenPoints::NONE,
        });
        Some(Phase::PathRequested { id, since: now })
    }

    /// Where to drive in from `pose` (the pre-goal) for the docking `goal` ([x, y, yaw, d]):
    /// the goal, or the nearest of [`DOCK_SHIFTS_M`] along the table, whose straight line in
    /// the range sensor sees clear (the footprint with the docking shape's margin, facing along
    /// the line, every 5 cm) and, for a moved goal, the map too. A moved goal is reported. `None`
    /// when the scan shows every one of them blocked (a chair pushed into the standing spot):
    /// the leg fails before the base drives in. Without a sensor, the goal as planned.
    fn docking_goal_in_the_scan(
        &mut self,
        pose: Pose2,
        goal: [f64; 4],
        inputs: &CycleInputs<'_>,
        outputs: &mut CycleOutputs,
    ) -> Option<(f64, f64)> {
        let Some(scan) = inputs.scan else {
            return Some((goal[0], goal[1]));
        };
        let (s, c) = goal[2].sin_cos();
        let chosen = DOCK_SHIFTS_M.iter().copied().find_map(|shift| {
            let (gx, gy) = (goal[0] - s * shift, goal[1] + c * shift);
            let map_clear =
                shift == 0.0 || self.docking.segment_free((pose.x_m, pose.y_m), (gx, gy));
            (map_clear && scan_line_clear(pose, (gx, gy), scan, &self.config.robot))
                .then_some((shift, gx, gy))
        })?;
        let (shift, gx, gy) = chosen;
        if shift != 0.0 {
            self.event(
                EventKind::Obstacle,
                inputs.now,
                format_args!(
                    "standing spot moved {:+.0} cm along the table to ({gx:.3}, {gy:.3}): the scan sees something on the way in",
                    shift * 100.0
                ),
                outputs,
            );
        }
        Some((gx, gy))
    }

    /// When a leg must have ended: the factor times its planned (or straight-line) travel time,
    /// plus the slack; a travel cost no duration can hold counts as the straight line's.
    fn leg_deadline(&self, step: &TaskStep, pose: Pose2, now: Duration) -> Duration {
        let straight_s = pose.distance_m(&Pose2::new(step.x_m, step.y_m, 0.0))
            / self.config.robot.speed_mps.max(0.05);
        let planned = step.travel_cost_s.max(straight_s);
        let allowed = Duration::try_from_secs_f64(planned * self.config.leg_time_factor)
            .or_else(|_| Duration::try_from_secs_f64(straight_s * self.config.leg_time_factor))
            .unwrap_or(Duration::ZERO);
        now.saturating_add(allowed)
            .saturating_add(self.config.leg_slack)
    }

    pub(super) fn leg_failed(
        &mut self,
        step: &TaskStep,
        now: Duration,
        why: &str,
        outputs: &mut CycleOutputs,
    ) -> Option<Phase> {
        self.dock_goal = None;
        self.dock_blocked_since = None;
        self.velocity = Twist::ZERO;
        self.event(
            EventKind::LegFinished,
            now,
            format_args!("leg to ({:.2}, {:.2}) failed: {why}", step.x_m, step.y_m),
            outputs,
        );
        self.failed_legs += 1;
        if self.failed_legs > MAX_FAILED_LEGS {
            // The base cannot get anywhere from here: stop rather than ask forever. A safety
            // stop like every abort (the base ramps at the emergency deceleration, the arm is
            // stopped), reported as `Stuck`.
            self.abort(AbortReason::Stuck, now, outputs);
            return None;
        }
        // The unload that needed this leg cannot happen from here: let the planner decide.
        if let Some(next) = self.steps.get(self.step_index + 1).copied() {
            if next.kind() == Ok(TaskStepKind::Unload) {
                self.stats.unloads_failed += 1;
                self.request_plan(ReplanReason::LegFailed, now, Some(&next), outputs);
                return None;
            }
        }
        self.request_plan(ReplanReason::LegFailed, now, None, outputs);
        None
    }
}

/// Whether the range sensor's points (`scan`, base frame at `pose`) leave the straight line from
/// `pose` to `goal` clear: the footprint grown by [`DOCKING_LINE_MARGIN_M`], facing along the
/// line, every 5 cm. Allocation free.
fn scan_line_clear(
    pose: Pose2,
    goal: (f64, f64),
    scan: &motion_control::collision::Obstacles,
    robot: &world::RobotConfig,
) -> bool {
    let (s, c) = pose.yaw_rad.sin_cos();
    let (wx, wy) = (goal.0 - pose.x_m, goal.1 - pose.y_m);
    // The goal in the base frame; the line runs from the origin to it.
    let (gx, gy) = (c * wx + s * wy, -s * wx + c * wy);
    let d = gx.hypot(gy);
    let yaw = gy.atan2(gx);
    let length = robot.footprint.length_m + 2.0 * DOCKING_LINE_MARGIN_M;
    let width = robot.footprint.width_m + 2.0 * DOCKING_LINE_MARGIN_M;
    let reach = d + length.hypot(width);
    let steps = (d / 0.05).ceil() as usize;
    scan.iter()
        .map(|p| (f64::from(p[0]), f64::from(p[1])))
        .filter(|(x, y)| x.hypot(*y) <= reach)
        .all(|(x, y)| {
            (0..=steps).all(|k| {
                let t = if steps == 0 {
                    1.0
                } else {
                    k as f64 / steps as f64
                };
                !world::geometry::OrientedRect::new(t * gx, t * gy, length, width, yaw)
                    .contains_point(x, y)
            })
        })
}
