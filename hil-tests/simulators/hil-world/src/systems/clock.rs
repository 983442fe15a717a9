//! The clock's systems: the start of the mission (everyone joined), the end conditions, and
//! the step of simulated time.

use std::time::Duration;

use super::context::{Ctx, Flow, System};
use crate::report::MissionEnd;
use crate::secs;

/// Waits until the onboard processes joined; then the mission clock runs at its pace.
pub(crate) struct Join;

impl System for Join {
    fn name(&self) -> &'static str {
        "Join"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        if ctx.mission.joined {
            return Flow::Next;
        }
        let host = &mut ctx.world.host;
        let names: Vec<String> = host.participants().into_iter().map(|p| p.0).collect();
        if ctx.cfg.expect.iter().all(|e| names.iter().any(|n| n == e)) {
            // Their subscriptions exist once they wait for their first turn: only then does
            // the world publish its first frame and fix.
            host.settle();
            ctx.mission.joined = true;
            ctx.mission.start = Some(ctx.now);
            host.set_pace(ctx.cfg.pace);
            log::info!(
                "world: {names:?} joined at {:.3} s; mission starts",
                secs(ctx.now)
            );
            Flow::Next
        } else if ctx.wall_start.elapsed() > ctx.cfg.join_timeout {
            log::error!("world: onboard processes never joined ({names:?})");
            ctx.report.end = MissionEnd::NeverStarted;
            Flow::Stop
        } else {
            // Simulated time stays at zero (nothing is stepped) until everyone is there: how
            // long the processes take to start never shows in the mission, so the same
            // mission twice is the same, message for message. Connecting needs no step
            // (request/reply, and the controller sends a state package as soon as RTDE
            // streaming starts).
            std::thread::sleep(Duration::from_millis(2));
            Flow::Wait
        }
    }
}

/// The step's wall time, and the end: the mission ended and the linger passed (and a fault a
/// person releases was watched), or the time limit.
pub(crate) struct End;

impl System for End {
    fn name(&self) -> &'static str {
        "End"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        ctx.mission.step_wall += ctx.work_started.elapsed();
        ctx.report.timing.steps += 1;
        if let Some(end) = ctx.mission.ended_at {
            // A fault a person releases: watched until 3 s after its release too.
            let inj = &ctx.injector;
            let watched =
                inj.release_at.is_none() && inj.watch_until.is_none_or(|until| now >= until);
            if now >= end + ctx.cfg.linger && watched {
                return Flow::Stop;
            }
        }
        if let Some(start) = ctx.mission.start {
            if now.saturating_sub(start) > ctx.cfg.max_sim_time {
                ctx.report.end = MissionEnd::TimedOut;
                return Flow::Stop;
            }
        }
        Flow::Next
    }
}

/// One step of simulated time (a second at once when a clock-jump fault asks for it).
pub(crate) struct Advance;

impl System for Advance {
    fn name(&self) -> &'static str {
        "Advance"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        if ctx.injector.jump.take().is_some() {
            ctx.world.host.jump_to(now + Duration::from_secs(1));
        } else {
            ctx.world.host.advance_to(now + ctx.dt);
        }
        Flow::Next
    }
}
