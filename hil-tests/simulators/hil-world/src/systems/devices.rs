//! The devices' systems: the simulated RMP behind the CAN bus, the simulated UR5e, the range
//! sensor, and this step's readings of them.

use nalgebra::Point3;

use super::context::{Ctx, Flow, System};
use crate::{base_limits, secs};

/// The CAN bus's fault injector and the simulated RMP. Contact is not free: a base that would
/// move into furniture stays where it was, its drives stalled (one already touching, e.g. from
/// its start or a chair pushed against it, may move, so that it can get away).
pub(crate) struct Base;

impl System for Base {
    fn name(&self) -> &'static str {
        "Base"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        let world = &mut *ctx.world;
        let limits = base_limits(world.base.sim());
        let bus = world.base.bus_mut();
        bus.set_limits(limits);
        if let Err(e) = bus.set_now(now) {
            log::warn!("world: CAN injector: {e}");
        }
        let before = world.base.sim().kinematics();
        let pose_before = world.base_pose();
        if let Err(e) = world.base.poll(now) {
            log::warn!("world: sim-rmp: {e}");
        }
        let (scene, robot) = (&ctx.cfg.scene, &ctx.cfg.robot);
        if world::base_collides(scene, robot, world.base_pose())
            && !world::base_collides(scene, robot, pose_before)
        {
            world.base.sim_mut().block(before);
            ctx.mission.blocked_since_check = true;
        }
        ctx.reading.pose = world.base_pose();
        Flow::Next
    }
}

/// One RTDE cycle of the simulated UR5e (externally stepped).
pub(crate) struct Arm;

impl System for Arm {
    fn name(&self) -> &'static str {
        "Arm"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        if let Err(e) = ctx.world.arm.step() {
            log::warn!("world: sim-ur5e step: {e}");
        }
        Flow::Next
    }
}

/// The range sensor: every packet fired by now, from where the base is (a revolution's
/// packets spread over its 100 ms: the scan is skewed by the base's motion, as the real one
/// is).
pub(crate) struct Lidar;

impl System for Lidar {
    fn name(&self) -> &'static str {
        "Lidar"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        if let Some(lidar) = ctx.world.lidar.as_mut() {
            lidar.step(
                u64::try_from(ctx.now.as_micros()).unwrap_or(u64::MAX),
                ctx.reading.pose,
            );
        }
        Flow::Next
    }
}

/// This step's readings: the base's speed (which the fixes' error model follows), the arm's
/// state and the tool point in the world; the highest base speeds for the report.
pub(crate) struct Readings;

impl System for Readings {
    fn name(&self) -> &'static str {
        "Readings"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let world = &mut *ctx.world;
        let r = &mut ctx.reading;
        let pose = r.pose;
        let (v, w) = world.base.sim().velocity();
        let speed = f64::from(v).abs() + 0.3 * f64::from(w).abs();
        world.fixes.observe_motion(speed, secs(ctx.dt));
        let world_from_base = ur5e_kin::world_from_base(&pose);
        let snap = world.arm.snapshot();
        let max = &mut ctx.report.max_base_speed;
        max.0 = max.0.max(f64::from(v).abs());
        max.1 = max.1.max(f64::from(w).abs());
        let place = &ctx.cfg.robot.place;
        let flange = world_from_base * place.mount.base_from_arm() * place.arm.forward(&snap.q);
        r.tcp = flange * Point3::new(0.0, 0.0, place.tcp_offset_m);
        r.v = v;
        r.w = w;
        r.speed = speed;
        r.world_from_base = world_from_base;
        r.snap = snap;
        Flow::Next
    }
}
