//! What the world publishes on a schedule: the truth, the localisation fixes and the world's
//! heartbeat, the operator's enable and the overhead camera's frames.

use std::time::Duration;

use grop_clock::duration_ns as ns;
use grop_ipc::{BasePoseMsg, PoseFixKind, ProcessRole};

use super::context::{Ctx, Flow, System};
use crate::{TRUTH_PERIOD, WorldConfig, table_edge_y};

/// The truth on `world/truth`, 20 Hz, for the log (never read onboard).
#[derive(Default)]
pub(crate) struct Truth {
    next: Duration,
    seq: u64,
}

impl System for Truth {
    fn name(&self) -> &'static str {
        "Truth"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        if now >= self.next {
            self.next = now + TRUTH_PERIOD;
            self.seq += 1;
            let r = &ctx.reading;
            let _ = ctx.world.ports.truth.publish(&grop_ipc::TruthMsg {
                seq: self.seq,
                stamp_ns: ns(now),
                x_m: r.pose.x_m,
                y_m: r.pose.y_m,
                yaw_rad: r.pose.yaw_rad,
                speed_mps: f64::from(r.v),
                yaw_rate_radps: f64::from(r.w),
            });
        }
        Flow::Next
    }
}

/// Localisation fixes on `base/pose` every `fix_period`: a global fix, and one relative to
/// the table when the base stands near it ([`crate::fixes`]).
#[derive(Default)]
pub(crate) struct Fixes {
    next: Duration,
    seq: u64,
}

impl System for Fixes {
    fn name(&self) -> &'static str {
        "Fixes"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        if now < self.next {
            return Flow::Next;
        }
        let cfg = &ctx.cfg;
        let world = &mut *ctx.world;
        let pose = ctx.reading.pose;
        self.next = now + cfg.fix_period;
        let truth = [pose.x_m, pose.y_m, pose.yaw_rad];
        let mut g = world.fixes.global_fix(truth);
        if ctx.injector.take_fix_jump() {
            // 1.5 m to the side of the heading: a plausible, wrong fix.
            g[0] -= 1.5 * truth[2].sin();
            g[1] += 1.5 * truth[2].cos();
        }
        self.seq += 1;
        let m = &cfg.fixes;
        let _ = world.ports.poses.publish(&BasePoseMsg::fix(
            self.seq,
            ns(now),
            PoseFixKind::Global,
            g,
            m.leg_bias_sigma_m,
            m.leg_yaw_sigma_rad,
        ));
        let to_table = (pose.y_m - table_edge_y(&cfg.scene, pose.y_m)).abs();
        if let Some(t) = world.fixes.table_fix(truth, to_table) {
            self.seq += 1;
            let _ = world.ports.poses.publish(&BasePoseMsg::fix(
                self.seq,
                ns(now),
                PoseFixKind::TableRelative,
                t,
                m.table_sigma_m,
                m.table_yaw_sigma_rad,
            ));
        }
        Flow::Next
    }
}

/// The world's heartbeat, with each round of fixes (the same period, right after them).
#[derive(Default)]
pub(crate) struct Heartbeat {
    next: Duration,
    seq: u64,
}

impl System for Heartbeat {
    fn name(&self) -> &'static str {
        "Heartbeat"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        if now >= self.next {
            self.next = now + ctx.cfg.fix_period;
            self.seq += 1;
            let hb = self.seq;
            let _ = ctx.world.ports.health.publish_with(|h| {
                h.seq = hb;
                h.stamp_ns = ns(now);
                h.set_role(ProcessRole::World);
                h.pid = std::process::id();
            });
        }
        Flow::Next
    }
}

/// The operator's enable on `operator/enable`, when due (asked for by the executive, or
/// after a released fault).
#[derive(Default)]
pub(crate) struct Operator {
    seq: u64,
}

impl System for Operator {
    fn name(&self) -> &'static str {
        "Operator"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        if ctx.mission.enable_due.is_some_and(|due| now >= due) {
            ctx.mission.enable_due = None;
            self.seq += 1;
            let _ = ctx
                .world
                .ports
                .enable
                .publish(&grop_ipc::OperatorEnableMsg {
                    seq: self.seq,
                    stamp_ns: ns(now),
                    pid: std::process::id(),
                    reserved: 0,
                });
            ctx.world
                .world_event(grop_ipc::EventKind::Enable, now, "operator: enable given");
        }
        Flow::Next
    }
}

/// The overhead camera: real-size RGB frames on `camera/frame` every `camera_period` (the
/// injector may corrupt or narrow them).
pub(crate) struct Camera {
    next: Duration,
    frame_id: u64,
    camera: world::camera::OverheadCamera,
    frame_buf: Vec<u8>,
    rendered_once: bool,
}

impl Camera {
    pub(crate) fn new(cfg: &WorldConfig) -> Self {
        Self {
            next: Duration::ZERO,
            frame_id: 0,
            camera: world::camera::OverheadCamera::fitting_room_with(
                &cfg.scene,
                cfg.camera_px.0,
                cfg.camera_px.1,
            ),
            frame_buf: vec![0u8; (cfg.camera_px.0 * cfg.camera_px.1 * 3) as usize],
            rendered_once: false,
        }
    }
}

impl System for Camera {
    fn name(&self) -> &'static str {
        "Camera"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        if now < self.next {
            return Flow::Next;
        }
        let injector = &ctx.injector;
        let camera = &self.camera;
        self.next = now + ctx.cfg.camera_period;
        self.frame_id += 1;
        let mut header = grop_ipc::CameraFrameHeader::for_layout(
            self.frame_id,
            ns(now),
            &world::camera::FrameLayout::rgb8(*camera),
        );
        let corrupt = injector
            .camera_corrupt_until
            .is_some_and(|until| now < until);
        if corrupt {
            // A row stride shorter than a row: no consumer may read pixels from it.
            header.row_stride_bytes = camera.width_px;
        }
        if injector.camera_narrow {
            // The same rows, fewer columns: the frame's west quarter only.
            header.width_px = (camera.width_px / 4).max(1);
        }
        // The furniture does not move: render once, publish the same picture.
        if !self.rendered_once {
            self.rendered_once = true;
            if let Err(e) = world::camera::render_frame(&ctx.cfg.scene, camera, &mut self.frame_buf)
            {
                log::error!("world: camera: {e}");
            }
        }
        let frames = &mut ctx.world.ports.frames;
        let published = if corrupt {
            frames.publish_with(|f| f.header = header).is_ok()
        } else {
            // Only the image's bytes are written (not the whole 3.5 MiB buffer).
            let frame_buf = &self.frame_buf;
            frames
                .publish_frame(header, |dst| {
                    if dst.len() == frame_buf.len() {
                        dst.copy_from_slice(frame_buf);
                    }
                })
                .is_ok()
        };
        if published {
            ctx.report.timing.frames += 1;
        }
        Flow::Next
    }
}
