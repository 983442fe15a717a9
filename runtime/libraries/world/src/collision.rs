//! Base collision against the scene, and the scene as boxes for the arm's collision checks.

use nalgebra::{Point3, Vector3};
use planar::Pose2;
use ur5e_kin::ObstacleBox;

use crate::geometry::{OrientedRect, OverlapProbe};
use crate::robot::{BaseCollisionModel, RobotConfig};
use crate::scene::{Chair, Scene, TABLE_CENTER_Y_M};

/// Obstacles farther than this from the arm's base (m, in the floor plane) cannot be touched by
/// the arm: UR5e reach 0.85 m from the shoulder axis plus a Robotiq 2F-140 and margin. Boxes
/// beyond it are left out of [`Scene::obstacle_boxes`] so every IK check stays cheap.
pub const ARM_RELEVANCE_RADIUS_M: f64 = 1.6;

/// Thickness given to walls when they are handed to the arm as boxes (m).
const WALL_THICKNESS_M: f64 = 0.1;

/// Whether the base footprint at `base` touches a table, a chair or a wall (or leaves the room).
/// Tables count from the floor up: the base cannot drive under a table top. With
/// [`BaseCollisionModel::ChairDiscs`] (the authors' code) the base is a point instead.
/// The gap between the base's real footprint at `base` and the nearest table, chair or wall
/// (m; 0 in contact): what the HIL world reports as the closest call of a mission.
pub fn base_clearance(scene: &Scene, robot: &RobotConfig, base: Pose2) -> f64 {
    let footprint = robot.footprint.at(base.x_m, base.y_m, base.yaw_rad);
    let room = &scene.room;
    let walls = footprint
        .corners()
        .iter()
        .map(|&(x, y)| {
            (x - room.x_min_m)
                .min(room.x_max_m - x)
                .min(y - room.y_min_m)
                .min(room.y_max_m - y)
        })
        .fold(f64::INFINITY, f64::min)
        .max(0.0);
    let furniture = [
        scene.banquet_table.footprint(),
        scene.loading_table.footprint(),
    ]
    .into_iter()
    .chain(scene.chairs.iter().map(Chair::footprint))
    .map(|r| footprint.distance_to(&r))
    .fold(f64::INFINITY, f64::min);
    walls.min(furniture)
}

/// The base's footprint at `base` overlaps a wall, a table or a chair.
pub fn base_collides(scene: &Scene, robot: &RobotConfig, base: Pose2) -> bool {
    if let BaseCollisionModel::ChairDiscs { radius_m } = robot.base_collision {
        let r2 = radius_m * radius_m;
        return !scene.room.contains(base.x_m, base.y_m)
            || scene
                .banquet_table
                .footprint()
                .contains_point(base.x_m, base.y_m)
            || scene
                .loading_table
                .footprint()
                .contains_point(base.x_m, base.y_m)
            || scene
                .chairs
                .iter()
                .any(|c| (c.x_m - base.x_m).powi(2) + (c.y_m - base.y_m).powi(2) < r2);
    }
    let footprint = robot.footprint.at(base.x_m, base.y_m, base.yaw_rad);
    !scene.room.contains_rect(&footprint)
        || footprint.overlaps(&scene.banquet_table.footprint())
        || footprint.overlaps(&scene.loading_table.footprint())
        || scene
            .chairs
            .iter()
            .any(|c| c.footprint().overlaps(&footprint))
}

/// The box `[x0, x1] x [y0, y1]` grown by the reach of a base centred in it, plus a margin so
/// rounding can never drop a chair that touches.
fn near_box(robot: &RobotConfig, x0: f64, x1: f64, y0: f64, y1: f64) -> (f64, f64, f64, f64) {
    let reach_m = match robot.base_collision {
        BaseCollisionModel::ChairDiscs { radius_m } => radius_m,
        _ => 0.5 * robot.footprint.length_m.hypot(robot.footprint.width_m),
    };
    (
        x0 - reach_m - 0.01,
        x1 + reach_m + 0.01,
        y0 - reach_m - 0.01,
        y1 + reach_m + 0.01,
    )
}

/// Whether `chair` reaches into the grown box of [`near_box`].
fn chair_near(robot: &RobotConfig, c: &Chair, (x0, x1, y0, y1): (f64, f64, f64, f64)) -> bool {
    let (cx0, cx1, cy0, cy1) = c.footprint().bounds();
    // Disc model: the chair counts by its centre.
    let (cx0, cx1, cy0, cy1) = match robot.base_collision {
        BaseCollisionModel::ChairDiscs { .. } => (c.x_m, c.x_m, c.y_m, c.y_m),
        _ => (cx0, cx1, cy0, cy1),
    };
    cx1 >= x0 && cx0 <= x1 && cy1 >= y0 && cy0 <= y1
}

impl Scene {
    /// A copy of the scene keeping only the chairs a base centred inside the box
    /// `[x0, x1] x [y0, y1]` could touch (tables, walls and targets stay): [`base_collides`] on it
    /// answers exactly as on the whole scene for every base in the box, with fewer chairs to
    /// test. For many checks around one place (a location's candidate cells).
    pub fn chairs_near(&self, robot: &RobotConfig, x0: f64, x1: f64, y0: f64, y1: f64) -> Scene {
        let near_box = near_box(robot, x0, x1, y0, y1);
        let mut near = self.clone();
        near.chairs.retain(|c| chair_near(robot, c, near_box));
        near
    }

    /// Everything the arm may hit, as world-frame boxes for ur5e-kin: the robot's own base body
    /// (footprint up to `footprint.body_height_m`), the tables (floor to top), chairs (floor to
    /// backrest) and walls, keeping only boxes within [`ARM_RELEVANCE_RADIUS_M`] of the arm base.
    pub fn obstacle_boxes(&self, robot: &RobotConfig, base: Pose2) -> Vec<ObstacleBox> {
        let mut boxes = Vec::with_capacity(8);
        self.obstacle_boxes_into(robot, base, &mut boxes);
        boxes
    }

    /// As [`Scene::obstacle_boxes`], into a reused vector (cleared first): no allocation once
    /// the vector has grown.
    #[allow(
        clippy::too_many_lines,
        reason = "one block per kind of obstacle (furniture, walls, the arm's own base)"
    )]
    pub fn obstacle_boxes_into(
        &self,
        robot: &RobotConfig,
        base: Pose2,
        boxes: &mut Vec<ObstacleBox>,
    ) {
        boxes.clear();
        let (sin_yaw, cos_yaw) = base.yaw_rad.sin_cos();
        let mount = &robot.place.mount;
        let arm_x = base.x_m + cos_yaw * mount.forward_m - sin_yaw * mount.lateral_m;
        let arm_y = base.y_m + sin_yaw * mount.forward_m + cos_yaw * mount.lateral_m;
        let relevant = |x0: f64, x1: f64, y0: f64, y1: f64| {
            let dx = (x0 - arm_x).max(arm_x - x1).max(0.0);
            let dy = (y0 - arm_y).max(arm_y - y1).max(0.0);
            dx * dx + dy * dy <= ARM_RELEVANCE_RADIUS_M * ARM_RELEVANCE_RADIUS_M
        };

        let body = robot.footprint;
        boxes.push(ObstacleBox {
            center: Point3::new(base.x_m, base.y_m, 0.5 * body.body_height_m),
            half_extents: Vector3::new(
                0.5 * body.length_m,
                0.5 * body.width_m,
                0.5 * body.body_height_m,
            ),
            yaw_rad: base.yaw_rad,
        });

        let bt = &self.banquet_table;
        if relevant(bt.x_min_m(), bt.x_max_m(), bt.y_min_m(), bt.y_max_m()) {
            // Only the stretch of the long table near the arm: a 13.5 m box would be exact too,
            // but a short one keeps the arm's bounding checks tight.
            let x0 = bt.x_min_m().max(arm_x - ARM_RELEVANCE_RADIUS_M);
            let x1 = bt.x_max_m().min(arm_x + ARM_RELEVANCE_RADIUS_M);
            boxes.push(ObstacleBox {
                center: Point3::new(0.5 * (x0 + x1), TABLE_CENTER_Y_M, 0.5 * bt.top_height_m),
                half_extents: Vector3::new(
                    0.5 * (x1 - x0),
                    0.5 * bt.depth_m,
                    0.5 * bt.top_height_m,
                ),
                yaw_rad: 0.0,
            });
        }
        let lt = &self.loading_table;
        let (lx0, lx1, ly0, ly1) = lt.footprint().bounds();
        if relevant(lx0, lx1, ly0, ly1) {
            boxes.push(ObstacleBox {
                center: Point3::new(lt.center_x_m, lt.center_y_m, 0.5 * lt.top_height_m),
                half_extents: Vector3::new(
                    0.5 * lt.length_m,
                    0.5 * lt.depth_m,
                    0.5 * lt.top_height_m,
                ),
                yaw_rad: 0.0,
            });
        }
        for chair in &self.chairs {
            let (x0, x1, y0, y1) = chair.footprint().bounds();
            if relevant(x0, x1, y0, y1) {
                boxes.push(ObstacleBox {
                    center: Point3::new(chair.x_m, chair.y_m, 0.5 * chair.height_m),
                    half_extents: Vector3::new(
                        0.5 * chair.depth_m,
                        0.5 * chair.width_m,
                        0.5 * chair.height_m,
                    ),
                    yaw_rad: chair.yaw_rad,
                });
            }
        }
        let room = &self.room;
        let wall_height_m = 3.0;
        let t = WALL_THICKNESS_M;
        let walls = [
            (
                room.x_min_m - t,
                room.x_min_m,
                room.y_min_m - t,
                room.y_max_m + t,
            ),
            (
                room.x_max_m,
                room.x_max_m + t,
                room.y_min_m - t,
                room.y_max_m + t,
            ),
            (
                room.x_min_m - t,
                room.x_max_m + t,
                room.y_min_m - t,
                room.y_min_m,
            ),
            (
                room.x_min_m - t,
                room.x_max_m + t,
                room.y_max_m,
                room.y_max_m + t,
            ),
        ];
        for (x0, x1, y0, y1) in walls {
            if relevant(x0, x1, y0, y1) {
                boxes.push(ObstacleBox {
                    center: Point3::new(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * wall_height_m),
                    half_extents: Vector3::new(
                        0.5 * (x1 - x0),
                        0.5 * (y1 - y0),
                        0.5 * wall_height_m,
                    ),
                    yaw_rad: 0.0,
                });
            }
        }
    }
}

/// [`base_collides`] for many bases at one heading whose centres lie in one box (a location's
/// candidate cells): the obstacles' footprints (tables, the chairs a base in the box can touch)
/// and the base footprint's orientation are computed once, so each check is only the overlap
/// tests. Answers exactly as `base_collides(scene, robot, pose)` for every pose with this yaw and
/// its centre in the box (the same floating-point operations on the same values).
#[derive(Debug, Clone)]
pub struct BaseCollisionChecker {
    room: crate::scene::Room,
    /// The base footprint at (0, 0) with the checker's yaw; moved per check.
    base: OrientedRect,
    /// The base against each table (the footprint model).
    table_probes: [OverlapProbe; 2],
    /// The tables themselves, for the disc model's point test.
    tables: [OrientedRect; 2],
    /// The base against each chair that a base in the box can touch.
    chairs: Vec<OverlapProbe>,
    /// Chair centres, for the disc model.
    chair_centres: Vec<(f64, f64)>,
    /// `Some(r^2)`: [`BaseCollisionModel::ChairDiscs`] of radius r.
    disc_r2: Option<f64>,
}

impl BaseCollisionChecker {
    /// A checker for bases facing `yaw_rad` centred inside `[x0, x1] x [y0, y1]`.
    pub fn new(
        scene: &Scene,
        robot: &RobotConfig,
        yaw_rad: f64,
        (x0, x1, y0, y1): (f64, f64, f64, f64),
    ) -> Self {
        let grown = near_box(robot, x0, x1, y0, y1);
        let near = scene.chairs.iter().filter(|c| chair_near(robot, c, grown));
        let disc_r2 = match robot.base_collision {
            BaseCollisionModel::ChairDiscs { radius_m } => Some(radius_m * radius_m),
            _ => None,
        };
        let base = robot.footprint.at(0.0, 0.0, yaw_rad);
        let (chairs, chair_centres) = if disc_r2.is_some() {
            (Vec::new(), near.map(|c| (c.x_m, c.y_m)).collect())
        } else {
            (
                near.map(|c| OverlapProbe::new(&c.footprint(), &base))
                    .collect(),
                Vec::new(),
            )
        };
        let tables = [
            scene.banquet_table.footprint(),
            scene.loading_table.footprint(),
        ];
        Self {
            room: scene.room,
            base,
            table_probes: tables.map(|t| OverlapProbe::new(&t, &base)),
            tables,
            chairs,
            chair_centres,
            disc_r2,
        }
    }

    /// Whether a base at (`x_m`, `y_m`) with the checker's yaw touches a table, a chair or a
    /// wall (or leaves the room).
    pub fn collides(&self, x_m: f64, y_m: f64) -> bool {
        if let Some(r2) = self.disc_r2 {
            return !self.room.contains(x_m, y_m)
                || self.tables.iter().any(|t| t.contains_point(x_m, y_m))
                || self
                    .chair_centres
                    .iter()
                    .any(|&(cx, cy)| (cx - x_m).powi(2) + (cy - y_m).powi(2) < r2);
        }
        let mut footprint = self.base;
        footprint.center_x_m = x_m;
        footprint.center_y_m = y_m;
        !self.room.contains_rect(&footprint)
            || self.table_probes[0].overlaps_at(x_m, y_m)
            || self.table_probes[1].overlaps_at(x_m, y_m)
            || self.chairs.iter().any(|c| c.overlaps_at(x_m, y_m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// The checker answers exactly as `base_collides` on the whole scene, for bases anywhere in
    /// its box, both facing yaws and a few odd ones, both collision models, evaluation scenes
    /// with 0 to 30 chairs.
    #[test]
    fn checker_equals_base_collides() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let footprint = RobotConfig::default();
        let discs = RobotConfig {
            base_collision: BaseCollisionModel::ChairDiscs { radius_m: 0.45 },
            ..RobotConfig::default()
        };
        let (mut free, mut blocked) = (0, 0);
        for seed in 0..6 {
            for chairs in [0, 15, 20, 25, 30] {
                let scene = crate::generate::evaluation_scene(seed, chairs, 30);
                for robot in [&footprint, &discs] {
                    for yaw in [
                        std::f64::consts::FRAC_PI_2,
                        -std::f64::consts::FRAC_PI_2,
                        0.3,
                    ] {
                        let x0 = rng.random_range(-9.0..8.0);
                        let y0 = rng.random_range(4.0..7.5);
                        let (x1, y1) = (x0 + 1.5, y0 + 0.5);
                        let checker =
                            BaseCollisionChecker::new(&scene, robot, yaw, (x0, x1, y0, y1));
                        for _ in 0..200 {
                            let (x, y) = (rng.random_range(x0..=x1), rng.random_range(y0..=y1));
                            let expected = base_collides(
                                &scene,
                                robot,
                                Pose2 {
                                    x_m: x,
                                    y_m: y,
                                    yaw_rad: yaw,
                                },
                            );
                            assert_eq!(checker.collides(x, y), expected, "seed {seed} ({x}, {y})");
                            if expected { blocked += 1 } else { free += 1 }
                        }
                    }
                }
            }
        }
        // Both answers occur often: the comparison is not vacuous.
        assert!(
            free > 1000 && blocked > 1000,
            "free {free}, blocked {blocked}"
        );
    }
}
