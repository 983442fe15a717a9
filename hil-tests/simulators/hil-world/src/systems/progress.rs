//! The mission's bookkeeping: legs (realised vs commanded goals), the trajectory and the
//! progress line.

use std::time::Duration;

use grop_ipc::TaskStepKind;

use super::context::{Ctx, Flow, System};
use crate::objects::{ObjectState, Verdict};
use crate::report::LegRecord;
use crate::{max_abs, secs};

/// Leg bookkeeping: a start after standing still begins a new leg; when the executive reached
/// a goal, the realised pose against the nearest commanded one.
pub(crate) struct Legs {
    was_moving: bool,
    /// The current leg's goal is recorded (or there is no leg yet).
    leg_recorded: bool,
}

impl Legs {
    /// Before the first step: no leg to record.
    pub(crate) fn new() -> Self {
        Self {
            was_moving: false,
            leg_recorded: true,
        }
    }
}

impl System for Legs {
    fn name(&self) -> &'static str {
        "Legs"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        let m = &mut ctx.mission;
        let pose = ctx.reading.pose;
        if ctx.reading.speed > 0.01 {
            if !self.was_moving && m.still_s >= ctx.cfg.fixes.still_before_leg_s {
                m.collided_this_leg = false;
                self.leg_recorded = false;
            }
            if m.first_motion.is_none() && m.first_plan.is_some() {
                m.first_motion = Some(secs(now));
            }
            m.still_s = 0.0;
            self.was_moving = true;
        } else {
            m.still_s += secs(ctx.dt);
            self.was_moving = false;
        }
        // The executive reached a goal: realised vs commanded.
        if !self.leg_recorded && m.goal_reached_pending {
            m.goal_reached_pending = false;
            self.leg_recorded = true;
            let goal = m
                .latest_plan
                .iter()
                .filter(|s| s.kind() == Ok(TaskStepKind::Navigate))
                .map(|s| [s.x_m, s.y_m, s.yaw_rad])
                .min_by(|a, b| {
                    let da = (a[0] - pose.x_m).hypot(a[1] - pose.y_m);
                    let db = (b[0] - pose.x_m).hypot(b[1] - pose.y_m);
                    da.total_cmp(&db)
                });
            if let Some(goal) = goal {
                if (goal[0] - pose.x_m).hypot(goal[1] - pose.y_m) < 0.6 {
                    let b = ctx.world.fixes.bias();
                    ctx.report.legs.push(LegRecord {
                        t_s: secs(now),
                        commanded: goal,
                        realised: [pose.x_m, pose.y_m, pose.yaw_rad],
                        fix_bias: [b[0], b[1]],
                    });
                }
            }
        }
        Flow::Next
    }
}

/// The true pose, every 200 ms, for the report.
#[derive(Default)]
pub(crate) struct Trajectory {
    next: Duration,
}

impl System for Trajectory {
    fn name(&self) -> &'static str {
        "Trajectory"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        if now >= self.next {
            self.next = now + Duration::from_millis(200);
            let pose = ctx.reading.pose;
            ctx.report
                .trajectory
                .push([secs(now), pose.x_m, pose.y_m, pose.yaw_rad]);
        }
        Flow::Next
    }
}

/// A progress line every `progress_every` of simulated time (when asked for).
#[derive(Default)]
pub(crate) struct Progress {
    next: Duration,
}

impl System for Progress {
    fn name(&self) -> &'static str {
        "Progress"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        if let Some(every) = ctx.cfg.progress_every {
            if now >= self.next {
                self.next = now + every;
                let objects = ctx.world.objects.objects();
                let placed = objects
                    .iter()
                    .filter(|o| {
                        matches!(
                            o.state,
                            ObjectState::Released {
                                verdict: Verdict::Placed,
                                ..
                            }
                        )
                    })
                    .count();
                let r = &ctx.reading;
                println!(
                    "progress t={:.1} x={:.2} y={:.2} v={:.2} arm={:.2} placed={placed}/{}",
                    secs(now),
                    r.pose.x_m,
                    r.pose.y_m,
                    r.v,
                    max_abs(&r.snap.qd),
                    objects.len()
                );
            }
        }
        Flow::Next
    }
}
