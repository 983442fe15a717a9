//! The fault injector's hooks in the step (docs/reliability.md): the strike and what lasts
//! (`World::inject`, [`crate::injector`]), the operator's enable after a release, and what the
//! report records after the fault.

use super::context::{Ctx, Flow, System};
use crate::{max_abs, secs};

/// Strikes when the fault's trigger comes, keeps up what lasts, releases.
pub(crate) struct Inject;

impl System for Inject {
    fn name(&self) -> &'static str {
        "Inject"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        if let (Some(spec), Some(start)) = (ctx.cfg.fault, ctx.mission.start) {
            ctx.world
                .inject(spec, &mut ctx.injector, ctx.now, start, &mut ctx.report);
        }
        Flow::Next
    }
}

/// The operator enables once a released fault is clear (a restart is not asked for: the test
/// checks that nothing moves all the same).
pub(crate) struct EnableAfterRelease;

impl System for EnableAfterRelease {
    fn name(&self) -> &'static str {
        "EnableAfterRelease"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        if ctx.injector.enable_at.is_some_and(|t| now >= t) {
            ctx.injector.enable_at = None;
            ctx.mission.enable_due = Some(now);
            if let Some(rec) = ctx.report.fault.as_mut() {
                rec.enabled_after_release_at_s = Some(secs(now));
            }
        }
        Flow::Next
    }
}

/// After a fault struck: when base and arm stopped, the stops the controller was asked for,
/// how far things moved after a release; and the injector's triggers (speeds, gripper).
pub(crate) struct Watch;

impl System for Watch {
    fn name(&self) -> &'static str {
        "Watch"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        let r = &ctx.reading;
        let (v, w, pose, snap) = (r.v, r.w, r.pose, &r.snap);
        let injector = &mut ctx.injector;
        let arm = &ctx.world.arm;
        if let (Some(rec), Some(at)) = (ctx.report.fault.as_mut(), injector.at) {
            if now >= at {
                if rec.base_stopped_at_s.is_none()
                    && f64::from(v).abs() < 0.01
                    && f64::from(w).abs() < 0.01
                {
                    rec.base_stopped_at_s = Some(secs(now));
                }
                if rec.arm_stopped_at_s.is_none() && max_abs(&snap.qd) < 0.01 {
                    rec.arm_stopped_at_s = Some(secs(now));
                }
                let stops = arm.with_robot(|r| r.stops_asked());
                let before = injector.stops_at_fault;
                if rec.arm_stop_asked_at_s.is_none() && stops.stop_programs > before.stop_programs {
                    rec.arm_stop_asked_at_s = Some(secs(now));
                }
                rec.dashboard_stops = stops.dashboard.saturating_sub(before.dashboard);
                if let Some((xy, q)) = injector.release_pose {
                    let moved = (pose.x_m - xy[0]).hypot(pose.y_m - xy[1]);
                    rec.base_moved_after_release_m = rec.base_moved_after_release_m.max(moved);
                    let turned = snap
                        .q
                        .iter()
                        .zip(q)
                        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
                    rec.arm_moved_after_release_rad = rec.arm_moved_after_release_rad.max(turned);
                }
            }
        }
        injector.base_speed = f64::from(v).abs();
        injector.arm_speed = max_abs(&snap.qd);
        injector.gripper_active = arm.with_robot(|r| r.gripper.is_active());
        Flow::Next
    }
}
