//! The objects' systems: loading at the station, and the tray, gripper, release and judgement
//! ([`crate::objects`]).

use grop_ipc::LoadRequestMsg;

use super::context::{Ctx, Flow, System};
use crate::objects::ObjectEvent;

/// The station loads exactly what the executive asks for, once per request, once the base
/// stands there.
#[derive(Default)]
pub(crate) struct Loads {
    /// The load request the station has not served yet (the newest; one load per request).
    pending: Option<LoadRequestMsg>,
}

impl System for Loads {
    fn name(&self) -> &'static str {
        "Loads"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        let world = &mut *ctx.world;
        while let Ok(Some(req)) = world.ports.loads.try_recv() {
            if let Some(old) = self.pending.replace(*req) {
                world.world_event(
                    grop_ipc::EventKind::Loaded,
                    now,
                    &format!(
                        "load request {} superseded by {} before the base stood at the station: nothing loaded for it",
                        old.request_id, req.request_id
                    ),
                );
            }
        }
        let station = ctx.cfg.scene.loading_station;
        let pose = ctx.reading.pose;
        if ctx.mission.still_s >= 1.0
            && (pose.x_m - station.x_m).hypot(pose.y_m - station.y_m) < 0.5
        {
            if let Some(req) = self.pending.take() {
                let detail = match world.objects.load(req.object_mask, &req.slots) {
                    Some(ObjectEvent::Loaded { mask }) if mask == req.object_mask => format!(
                        "load request {}: objects {mask:#x} put on the tray",
                        req.request_id
                    ),
                    Some(ObjectEvent::Loaded { mask }) => format!(
                        "load request {}: objects {mask:#x} put on the tray of {:#x} asked for (the rest is not at the station or the tray is full)",
                        req.request_id, req.object_mask
                    ),
                    _ => format!(
                        "load request {}: nothing of {:#x} at the station or room on the tray",
                        req.request_id, req.object_mask
                    ),
                };
                world.world_event(grop_ipc::EventKind::Loaded, now, &detail);
            }
        }
        Flow::Next
    }
}

/// The tray and the gripper: an object in the closing fingers is held, one let go is judged
/// where it lands (a world event).
pub(crate) struct Tray;

impl System for Tray {
    fn name(&self) -> &'static str {
        "Tray"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        let world = &mut *ctx.world;
        let m = &ctx.mission;
        let r = &ctx.reading;
        let table = &ctx.cfg.scene.banquet_table;
        let (width, event) = world.objects.step_gripper(
            &r.world_from_base,
            r.tcp,
            r.snap.gripper_opening_m,
            m.collided_this_leg,
            m.in_collision[0] || m.in_collision[1],
            |x, y| table.top_contains(x, y),
        );
        world.arm.set_gripper_object(width);
        if let Some(ObjectEvent::Judged {
            index,
            verdict,
            error_m,
        }) = event
        {
            world.world_event(
                grop_ipc::EventKind::ObjectJudged,
                now,
                &format!(
                    "object {index}: {verdict:?}, {:.3} m from its target",
                    error_m
                ),
            );
        }
        Flow::Next
    }
}
