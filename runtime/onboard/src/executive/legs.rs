//! The legs of a mission: back out from the table, ask for the path, follow it, turn to the
//! goal heading, settle, and dock straight in at a table goal. Part of [`MissionCore`]: each
//! phase reads the cycle's inputs and writes the velocity and worker jobs into its outputs.

use std::time::Duration;

use grop_ipc::{EventKind, ReplanReason, TaskStep, TaskStepKind};
use motion_control::follower::FollowStep;
use motion_control::{Pose2, Twist};

use super::AbortReason;
use super::cycle::{CycleInputs, CycleOutputs};
use super::mission::{DOCKING_LINE_MARGIN_M, MissionCore, Phase};
use super::worker::{Answer, Job, PathFailure, SeenPoints};
use crate::localisation::{PlanarPose, wrap};

/// Legs that may fail in a row before the mission is given up.
pub const MAX_FAILED_LEGS: u32 = 3;

/// Backing-out speed from the table, m/s.
pub const REVERSE_SPEED_MPS: f32 = 0.15;

/// Docking / back-out distances tried, longest first, m: the base turns at the pre-goal this
/// far behind a table goal, then drives straight in.
pub const DOCKING_DISTANCES_M: [f64; 5] = [1.0, 0.75, 0.45, 0.3, 0.15];

/// At least the last this many metres to a docking goal (and the first ones backing out) use
/// the collision monitor's docking shape at crawl speed; a longer straight stretch, checked
/// free with [`DOCKING_LINE_MARGIN_M`], uses it all the way.
pub const DOCKING_SHAPE_RANGE_M: f64 = 0.5;

/// Sideways shifts of a docking goal tried, nearest first (m, across the goal's heading): the
/// arm plans from the pose the base reaches, so a few centimetres along the table cost nothing
/// and can buy a clear line in past a chair.
pub const DOCK_SHIFTS_M: [f64; 11] = [
    0.0, 0.02, -0.02, 0.04, -0.04, 0.06, -0.06, 0.08, -0.08, 0.1, -0.1,
];

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
        pose: PlanarPose,
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
                let p = Pose2 {
                    x_m: pose.x_m as f32,
                    y_m: pose.y_m as f32,
                    yaw_rad: pose.yaw_rad as f32,
                };
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
                let err = wrap(step.yaw_rad - pose.yaw_rad);
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
                    let err = pose.distance_m(&PlanarPose::new(step.x_m, step.y_m, 0.0));
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

    /// Starts a leg: back out from the table first if the robot stands at it, then ask for the
    /// path (to a pre-goal in front of a table goal, see [`Self::request_path`]).
    fn start_leg(
        &mut self,
        step: &TaskStep,
        pose: PlanarPose,
        now: Duration,
        outputs: &mut CycleOutputs,
    ) -> Option<Phase> {
        if std::mem::take(&mut self.at_table) {
            // Straight back, away from the table, as far as the map allows (up to the docking
            // distance): turning in place next to the table would sweep the footprint into it.
            // The same rule as docking's: straight back to where a turn in place is free.
            let distance_m = self
                .free_stretch(pose.x_m, pose.y_m, pose.yaw_rad)
                .unwrap_or(0.0);
            if distance_m > 0.0 {
                return Some(Phase::Reversing {
                    start: pose,
                    distance_m,
                    deadline: now
                        + Duration::from_secs_f64(3.0 * distance_m / REVERSE_SPEED_MPS as f64),
                });
            }
        }
        self.request_path(step, pose, now, outputs)
    }

    /// Asks the worker for the leg's path. A goal followed by an unload is docked: the path
    /// ends at a pre-goal straight behind the goal (facing the table), where the base turns,
    /// then drives straight in, so it never turns next to the table or between chairs.
    fn request_path(
        &mut self,
        step: &TaskStep,
        pose: PlanarPose,
        now: Duration,
        outputs: &mut CycleOutputs,
    ) -> Option<Phase> {
        let id = self.next_job_id;
        self.next_job_id += 1;
        self.dock_goal = None;
        let mut to = (step.x_m, step.y_m);
        self.dock = None;
        // A goal next to a table (an unload's, or the loading station's) is docked.
        let table_next = self
            .steps
            .get(self.step_index + 1)
            .is_some_and(|n| matches!(n.kind(), Ok(TaskStepKind::Unload | TaskStepKind::Load)));
        if table_next {
            // No straight way in: the standing spot itself is not free on the map (the learned
            // feasibility is no geometric check). Driving there and turning would push the
            // base into the furniture; the leg fails before it starts.
            let Some((x, y, d)) = self.docking_spot(step) else {
                return self.leg_failed(
                    step,
                    now,
                    "no straight way in to the standing spot",
                    outputs,
                );
            };
            let (s, c) = step.yaw_rad.sin_cos();
            to = (x - c * d, y - s * d);
            self.dock = Some([x, y, step.yaw_rad, d]);
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

    /// How far behind the pose (`x`, `y`, `yaw`) the base can stand and still drive straight
    /// to it: the longest of [`DOCKING_DISTANCES_M`] whose straight line is free for the
    /// footprint at `yaw` (with [`SOUND_LINE_MARGIN_M`], else [`DOCKING_LINE_MARGIN_M`]) and
    /// where a turn in place is free (with [`TURN_MARGIN_M`], every 15 degrees); failing that,
    /// the longest free line. The pre-goal of a docking (behind a table goal) and the end of a
    /// back-out (behind the base at the table).
    ///
    /// [`SOUND_LINE_MARGIN_M`]: super::mission::SOUND_LINE_MARGIN_M
    /// [`TURN_MARGIN_M`]: super::mission::TURN_MARGIN_M
    fn free_stretch(&self, x: f64, y: f64, yaw: f64) -> Option<f64> {
        self.sound_stretch(x, y, yaw)
            .or_else(|| self.stretch_with(x, y, yaw, &self.line_robot))
    }

    /// Where to dock for `step`, and from how far: the goal, or the nearest of
    /// [`DOCK_SHIFTS_M`] along the table, whose line in is free with [`SOUND_LINE_MARGIN_M`]
    /// and whose pre-goal is free to turn at; failing that, the nearest with a line free by
    /// [`DOCKING_LINE_MARGIN_M`] (at each spot, a pre-goal free to turn at first). None: no
    /// spot within the shifts is free on the map.
    ///
    /// [`SOUND_LINE_MARGIN_M`]: super::mission::SOUND_LINE_MARGIN_M
    fn docking_spot(&self, step: &TaskStep) -> Option<(f64, f64, f64)> {
        let (s, c) = step.yaw_rad.sin_cos();
        let yaw = step.yaw_rad;
        let spot = |shift: &f64| (step.x_m - s * shift, step.y_m + c * shift);
        DOCK_SHIFTS_M
            .iter()
            .find_map(|shift| {
                let (x, y) = spot(shift);
                self.sound_stretch(x, y, yaw).map(|d| (x, y, d))
            })
            .or_else(|| {
                DOCK_SHIFTS_M.iter().find_map(|shift| {
                    let (x, y) = spot(shift);
                    self.stretch_with(x, y, yaw, &self.line_robot)
                        .map(|d| (x, y, d))
                })
            })
    }

    /// The longest stretch whose line is free with [`SOUND_LINE_MARGIN_M`] and whose end is
    /// free to turn at.
    ///
    /// [`SOUND_LINE_MARGIN_M`]: super::mission::SOUND_LINE_MARGIN_M
    fn sound_stretch(&self, x: f64, y: f64, yaw: f64) -> Option<f64> {
        DOCKING_DISTANCES_M.iter().copied().find(|d| {
            self.line_free(x, y, yaw, *d, &self.sound_line_robot) && self.turn_free(x, y, yaw, *d)
        })
    }

    /// Whether the footprint (of `robot`) at `yaw` is free all along the line from `d` behind
    /// (`x`, `y`) to it, every 5 cm.
    fn line_free(&self, x: f64, y: f64, yaw: f64, d: f64, robot: &world::RobotConfig) -> bool {
        (0..=((d / 0.05).ceil() as usize))
            .all(|k| self.footprint_free(x, y, yaw, (k as f64 * 0.05).min(d), yaw, robot))
    }

    /// Whether a turn in place `d` behind (`x`, `y`) along `yaw` is free (with
    /// [`TURN_MARGIN_M`], every 15 degrees).
    ///
    /// [`TURN_MARGIN_M`]: super::mission::TURN_MARGIN_M
    fn turn_free(&self, x: f64, y: f64, yaw: f64, d: f64) -> bool {
        (0..12).all(|k| {
            let heading = yaw + f64::from(k) * std::f64::consts::PI / 12.0;
            self.footprint_free(x, y, yaw, d, heading, &self.turn_robot)
        })
    }

    /// Whether `robot`'s footprint at `heading`, `d` behind (`x`, `y`) along `yaw`, is free.
    fn footprint_free(
        &self,
        x: f64,
        y: f64,
        yaw: f64,
        d: f64,
        heading: f64,
        robot: &world::RobotConfig,
    ) -> bool {
        let (s, c) = yaw.sin_cos();
        !world::base_collides(
            &self.scene,
            robot,
            world::BasePose {
                x_m: x - c * d,
                y_m: y - s * d,
                yaw_rad: heading,
            },
        )
    }

    /// The longest line free for `line_robot` whose end is free to turn at, else the longest
    /// free line.
    fn stretch_with(
        &self,
        x: f64,
        y: f64,
        yaw: f64,
        line_robot: &world::RobotConfig,
    ) -> Option<f64> {
        let lines: heapless::Vec<f64, 5> = DOCKING_DISTANCES_M
            .iter()
            .copied()
            .filter(|d| self.line_free(x, y, yaw, *d, line_robot))
            .collect();
        lines
            .iter()
            .copied()
            .find(|d| self.turn_free(x, y, yaw, *d))
            .or_else(|| lines.first().copied())
    }

    /// Where to drive in from `pose` (the pre-goal) for the docking `goal` ([x, y, yaw, d]):
    /// the goal, or the nearest of [`DOCK_SHIFTS_M`] along the table, whose straight line in
    /// the range sensor sees clear (the footprint with the docking shape's margin, facing along
    /// the line, every 5 cm) and, for a moved goal, the map too. A moved goal is reported. `None`
    /// when the scan shows every one of them blocked (a chair pushed into the standing spot):
    /// the leg fails before the base drives in. Without a sensor, the goal as planned.
    fn docking_goal_in_the_scan(
        &mut self,
        pose: PlanarPose,
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
            let map_clear = shift == 0.0 || self.segment_free((pose.x_m, pose.y_m), (gx, gy));
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

    /// Whether the footprint (with the docking line's margin) is free on the map all along the
    /// straight line from `a` to `b`, facing along it, every 5 cm.
    fn segment_free(&self, a: (f64, f64), b: (f64, f64)) -> bool {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let d = dx.hypot(dy);
        let yaw = dy.atan2(dx);
        (0..=((d / 0.05).ceil() as usize)).all(|k| {
            self.footprint_free(
                b.0,
                b.1,
                yaw,
                (k as f64 * 0.05).min(d),
                yaw,
                &self.line_robot,
            )
        })
    }

    /// When a leg must have ended: the factor times its planned (or straight-line) travel time,
    /// plus the slack; a travel cost no duration can hold counts as the straight line's.
    fn leg_deadline(&self, step: &TaskStep, pose: PlanarPose, now: Duration) -> Duration {
        let straight_s = pose.distance_m(&PlanarPose::new(step.x_m, step.y_m, 0.0))
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
    pose: PlanarPose,
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
