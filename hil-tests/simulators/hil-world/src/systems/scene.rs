//! The truth's systems: chairs the world moves, and contact of base and arm with the
//! furniture.

use std::time::Duration;

use ur5e_kin::ObstacleBox;

use super::context::{Ctx, Flow, System};
use crate::report::{CollisionRecord, Part};
use crate::{WorldConfig, moves, secs};

/// Moves chairs when due; the sensor, the contact checks and the camera see the new truth.
pub(crate) struct ChairMoves {
    mover: moves::Mover,
}

impl ChairMoves {
    pub(crate) fn new(cfg: &WorldConfig) -> Self {
        Self {
            mover: moves::Mover::new(&cfg.chair_moves),
        }
    }
}

impl System for ChairMoves {
    fn name(&self) -> &'static str {
        "ChairMoves"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        if self.mover.apply_due(ctx.now, &mut ctx.cfg.scene)
            && let Some(lidar) = ctx.world.lidar.as_mut()
        {
            lidar.set_scene(&ctx.cfg.scene);
        }
        Flow::Next
    }
}

/// Base and arm against the furniture, every 10 ms: the report's collisions and closest
/// approach, a world event at each new contact.
pub(crate) struct Contacts {
    next: Duration,
    obstacles: Vec<ObstacleBox>,
}

impl Default for Contacts {
    fn default() -> Self {
        Self {
            next: Duration::ZERO,
            obstacles: Vec::with_capacity(64),
        }
    }
}

impl System for Contacts {
    fn name(&self) -> &'static str {
        "Contacts"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        if now < self.next {
            return Flow::Next;
        }
        self.next = now + Duration::from_millis(10);
        let cfg = &ctx.cfg;
        let m = &mut ctx.mission;
        let report = &mut ctx.report;
        let (pose, snap) = (ctx.reading.pose, &ctx.reading.snap);
        let place = &cfg.robot.place;
        let blocked = std::mem::take(&mut m.blocked_since_check);
        let base_hit = world::base_collides(&cfg.scene, &cfg.robot, pose) || blocked;
        if m.start.is_some() {
            let gap = if blocked {
                0.0
            } else {
                world::base_clearance(&cfg.scene, &cfg.robot, pose)
            };
            if report.min_base_clearance.is_none_or(|(g, _)| gap < g) {
                report.min_base_clearance = Some((gap, [pose.x_m, pose.y_m, pose.yaw_rad]));
            }
        }
        cfg.scene
            .obstacle_boxes_into(&cfg.robot, pose, &mut self.obstacles);
        // The robot's own body (first box) is not furniture.
        let furniture = self.obstacles.get(1..).unwrap_or(&[]);
        let arm_hit = ur5e_kin::place::arm_touches_obstacles(place, pose, &snap.q, furniture);
        for (k, (hit, part)) in [(base_hit, Part::Base), (arm_hit, Part::Arm)]
            .into_iter()
            .enumerate()
        {
            if hit && !m.in_collision[k] {
                m.collided_this_leg = true;
                let obstacle = match part {
                    Part::Arm => furniture
                        .iter()
                        .find(|b| {
                            ur5e_kin::place::arm_collides(
                                place,
                                pose,
                                &snap.q,
                                std::slice::from_ref(*b),
                            )
                        })
                        .map(|b| [b.center.x, b.center.y, b.center.z]),
                    Part::Base => None,
                };
                report.collisions.push(CollisionRecord {
                    t_s: secs(now),
                    part,
                    base: [pose.x_m, pose.y_m, pose.yaw_rad],
                    q: snap.q,
                    obstacle,
                });
                ctx.world.world_event(
                    grop_ipc::EventKind::Collision,
                    now,
                    &format!(
                        "{part:?} touched furniture at ({:.2}, {:.2})",
                        pose.x_m, pose.y_m
                    ),
                );
            }
            m.in_collision[k] = hit;
        }
        Flow::Next
    }
}
