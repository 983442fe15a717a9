//! Docking and backing out, planned on the map: where the base stands to dock at a table goal
//! (the goal, or a few centimetres along the table for a clear line in), from how far behind it
//! it drives straight in (the pre-goal, where it turns), and how far it backs straight out
//! before its next leg. The planner node writes these into every plan it publishes
//! ([`Docking::annotate`]: `TaskStep::approach_m` and `back_out_m`); the executive follows
//! them, and moves a goal only because of what its range sensor shows (checked on the map with
//! [`Docking::segment_free`]). Nothing here looks at a scan.
//!
//! The rule, one for docking and backing out: a straight stretch at the goal's heading, the
//! longest of [`DOCKING_DISTANCES_M`] whose line is free for the footprint grown by
//! [`SOUND_LINE_MARGIN_M`] (else [`DOCKING_LINE_MARGIN_M`]) every 5 cm, and at whose end a
//! turn in place is free (footprint grown by [`TURN_MARGIN_M`], every 15 degrees); failing a
//! free turn, the longest free line.

use grop_ipc::{TaskStep, TaskStepKind};
use planar::Pose2;
use world::{RobotConfig, Scene};

/// Docking / back-out distances tried, longest first, m: the base turns at the pre-goal this
/// far behind a table goal, then drives straight in.
pub const DOCKING_DISTANCES_M: [f64; 5] = [1.0, 0.75, 0.45, 0.3, 0.15];

/// Margin around the footprint for the straight docking line at the goal's heading (m): the
/// collision monitor's docking shape.
pub const DOCKING_LINE_MARGIN_M: f64 = 0.01;

/// Margin around the footprint for a sound docking line (m): the monitor's docking shape plus
/// three sigmas of the range sensor's noise, so passing furniture does not trip the monitor.
/// Lines this free are preferred, a few centimetres along the table if need be
/// ([`DOCK_SHIFTS_M`]); a line free only by [`DOCKING_LINE_MARGIN_M`] is the fallback.
pub const SOUND_LINE_MARGIN_M: f64 = 0.04;

/// Sideways shifts of a docking goal tried, nearest first (m, across the goal's heading): the
/// arm plans from the pose the base reaches, so a few centimetres along the table cost nothing
/// and can buy a clear line in past a chair.
pub const DOCK_SHIFTS_M: [f64; 11] = [
    0.0, 0.02, -0.02, 0.04, -0.04, 0.06, -0.06, 0.08, -0.08, 0.1, -0.1,
];

/// Margin around the footprint for turning in place at a pre-goal (m): the monitor's stop zone
/// plus a few centimetres of localisation error.
pub const TURN_MARGIN_M: f64 = 0.06;

/// `TaskStep::approach_m` of a goal next to a table with no straight way in on the map: the
/// executive fails the leg before it drives (the learned feasibility is no geometric check).
pub const NO_WAY_IN: f64 = -1.0;

fn grown(robot: &RobotConfig, margin_m: f64) -> RobotConfig {
    let mut r = robot.clone();
    r.footprint.length_m += 2.0 * margin_m;
    r.footprint.width_m += 2.0 * margin_m;
    r
}

/// The map and the robot's footprints with the docking margins (see the module docs).
#[derive(Debug, Clone)]
pub struct Docking {
    scene: Scene,
    /// The footprint grown by [`DOCKING_LINE_MARGIN_M`].
    line_robot: RobotConfig,
    /// Grown by [`SOUND_LINE_MARGIN_M`].
    sound_line_robot: RobotConfig,
    /// Grown by [`TURN_MARGIN_M`].
    turn_robot: RobotConfig,
}

impl Docking {
    /// Docking on the map `scene` for `robot`.
    pub fn new(scene: Scene, robot: &RobotConfig) -> Self {
        Self {
            scene,
            line_robot: grown(robot, DOCKING_LINE_MARGIN_M),
            sound_line_robot: grown(robot, SOUND_LINE_MARGIN_M),
            turn_robot: grown(robot, TURN_MARGIN_M),
        }
    }

    /// Fills in the docking of a plan's `steps` for a base standing at `start` (x, y, yaw), at
    /// a table if `start_at_table`: every navigate step followed by a load or an unload docks
    /// (its goal moved along the table where [`Docking::docking_spot`] says, the same goal in
    /// the unload step, `approach_m` the pre-goal's distance, or [`NO_WAY_IN`]); every other
    /// navigate step has `approach_m` 0. A navigate step that leaves a table (after a load or
    /// an unload, or the plan's first when the base stands at one) has `back_out_m` the
    /// straight stretch back from where the base stands ([`Docking::free_stretch`]; 0 when
    /// none is free), every other 0.
    pub fn annotate(&self, steps: &mut [TaskStep], start: [f64; 3], start_at_table: bool) {
        // Where the base stands before each step, and whether at a table.
        let mut at = start;
        let mut at_table = start_at_table;
        for i in 0..steps.len() {
            match steps[i].kind() {
                Ok(TaskStepKind::Navigate) => {
                    let s = &mut steps[i];
                    s.back_out_m = if at_table {
                        self.free_stretch(at[0], at[1], at[2]).unwrap_or(0.0)
                    } else {
                        0.0
                    };
                    let docked = steps.get(i + 1).is_some_and(|n| {
                        matches!(n.kind(), Ok(TaskStepKind::Unload | TaskStepKind::Load))
                    });
                    let s = &mut steps[i];
                    s.approach_m = 0.0;
                    if docked {
                        match self.docking_spot(s.x_m, s.y_m, s.yaw_rad) {
                            Some((x, y, d)) => {
                                s.x_m = x;
                                s.y_m = y;
                                s.approach_m = d;
                            }
                            None => s.approach_m = NO_WAY_IN,
                        }
                    }
                    let (x, y, yaw) = (s.x_m, s.y_m, s.yaw_rad);
                    if let Some(n) = steps.get_mut(i + 1) {
                        if n.kind() == Ok(TaskStepKind::Unload) {
                            n.x_m = x;
                            n.y_m = y;
                        }
                    }
                    at = [x, y, yaw];
                    at_table = false;
                }
                Ok(TaskStepKind::Unload | TaskStepKind::Load) => {
                    steps[i].approach_m = 0.0;
                    steps[i].back_out_m = 0.0;
                    at_table = true;
                }
                Err(_) => {}
            }
        }
    }

    /// How far behind the pose (`x`, `y`, `yaw`) the base can stand and still drive straight
    /// to it (see the module docs). The pre-goal of a docking (behind a table goal) and the
    /// end of a back-out (behind the base at the table).
    pub fn free_stretch(&self, x: f64, y: f64, yaw: f64) -> Option<f64> {
        self.sound_stretch(x, y, yaw)
            .or_else(|| self.stretch_with(x, y, yaw, &self.line_robot))
    }

    /// Where to dock for the goal (`x`, `y`, `yaw`), and from how far: the goal, or the
    /// nearest of [`DOCK_SHIFTS_M`] along the table, whose line in is free with
    /// [`SOUND_LINE_MARGIN_M`] and whose pre-goal is free to turn at; failing that, the
    /// nearest with a line free by [`DOCKING_LINE_MARGIN_M`] (at each spot, a pre-goal free to
    /// turn at first). None: no spot within the shifts is free on the map.
    pub fn docking_spot(&self, x: f64, y: f64, yaw: f64) -> Option<(f64, f64, f64)> {
        let (s, c) = yaw.sin_cos();
        let spot = |shift: &f64| (x - s * shift, y + c * shift);
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

    /// Whether the footprint (with the docking line's margin) is free on the map all along the
    /// straight line from `a` to `b`, facing along it, every 5 cm.
    pub fn segment_free(&self, a: (f64, f64), b: (f64, f64)) -> bool {
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

    /// The longest stretch whose line is free with [`SOUND_LINE_MARGIN_M`] and whose end is
    /// free to turn at.
    fn sound_stretch(&self, x: f64, y: f64, yaw: f64) -> Option<f64> {
        DOCKING_DISTANCES_M.iter().copied().find(|d| {
            self.line_free(x, y, yaw, *d, &self.sound_line_robot) && self.turn_free(x, y, yaw, *d)
        })
    }

    /// Whether the footprint (of `robot`) at `yaw` is free all along the line from `d` behind
    /// (`x`, `y`) to it, every 5 cm.
    fn line_free(&self, x: f64, y: f64, yaw: f64, d: f64, robot: &RobotConfig) -> bool {
        (0..=((d / 0.05).ceil() as usize))
            .all(|k| self.footprint_free(x, y, yaw, (k as f64 * 0.05).min(d), yaw, robot))
    }

    /// Whether a turn in place `d` behind (`x`, `y`) along `yaw` is free (with
    /// [`TURN_MARGIN_M`], every 15 degrees).
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
        robot: &RobotConfig,
    ) -> bool {
        let (s, c) = yaw.sin_cos();
        !world::base_collides(
            &self.scene,
            robot,
            Pose2 {
                x_m: x - c * d,
                y_m: y - s * d,
                yaw_rad: heading,
            },
        )
    }

    /// The longest line free for `line_robot` whose end is free to turn at, else the longest
    /// free line.
    fn stretch_with(&self, x: f64, y: f64, yaw: f64, line_robot: &RobotConfig) -> Option<f64> {
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
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message
mod tests {
    use super::*;
    use grop_ipc::TableSide;
    use std::f64::consts::FRAC_PI_2;

    /// A plan as the planner node makes it: to the station, load, then two unloads at the near
    /// side of the banquet table.
    fn plan(scene: &Scene) -> Vec<TaskStep> {
        let (st, lt) = (&scene.loading_station, &scene.loading_table);
        let yaw = (lt.center_y_m - st.y_m).atan2(lt.center_x_m - st.x_m);
        let goal = |x: f64| [x, 5.2, FRAC_PI_2];
        let unload =
            |i: u32, g: [f64; 3]| TaskStep::unload(i, TableSide::Near, [g[0], 6.0, 0.8], g, 0.8);
        vec![
            TaskStep::navigate(st.x_m, st.y_m, yaw, 10.0),
            TaskStep::load(0b11, st.x_m, st.y_m),
            TaskStep::navigate(1.0, 5.2, FRAC_PI_2, 10.0),
            unload(0, goal(1.0)),
            TaskStep::navigate(-1.0, 5.2, FRAC_PI_2, 5.0),
            unload(1, goal(-1.0)),
        ]
    }

    #[test]
    fn every_table_goal_is_docked_and_every_leg_from_a_table_backs_out() {
        let scene = Scene::empty_paper_room();
        let docking = Docking::new(scene.clone(), &RobotConfig::default());
        let mut steps = plan(&scene);
        docking.annotate(&mut steps, [0.0, 1.0, 0.0], false);
        // From the start (not at a table): no back-out; the station is docked.
        assert_eq!(steps[0].back_out_m, 0.0);
        assert!(steps[0].approach_m > 0.0, "{:?}", steps[0]);
        // Every leg after the station and after an unload backs out, and docks: the empty
        // room leaves the full stretch at the banquet table.
        for i in [2, 4] {
            assert!(steps[i].back_out_m > 0.0, "step {i}: {:?}", steps[i]);
            assert_eq!(steps[i].approach_m, DOCKING_DISTANCES_M[0], "step {i}");
            // Nothing in the way: the goal as GROP chose it, the unload's the same.
            assert_eq!(
                (steps[i].x_m, steps[i].y_m),
                (steps[i + 1].x_m, steps[i + 1].y_m)
            );
        }
        assert_eq!((steps[2].x_m, steps[2].y_m), (1.0, 5.2));
        // The back-out after an unload is the stretch at the goal the base docked at.
        assert_eq!(
            Some(steps[4].back_out_m),
            docking.free_stretch(1.0, 5.2, FRAC_PI_2)
        );
        // Load and unload steps carry none.
        for i in [1, 3, 5] {
            assert_eq!((steps[i].approach_m, steps[i].back_out_m), (0.0, 0.0));
        }
        // A base standing at a table when it asked: the plan's first leg backs out first.
        let mut again = plan(&scene)[2..].to_vec();
        docking.annotate(&mut again, [1.0, 5.2, FRAC_PI_2], true);
        assert_eq!(again[0].back_out_m, steps[4].back_out_m);
    }

    #[test]
    fn a_chair_moves_the_goal_along_the_table_or_leaves_no_way_in() {
        let mut scene = Scene::empty_paper_room();
        // Grazing the line in to (1.0, 5.2): the goal moves a few centimetres along the table.
        scene.chairs.push(world::Chair {
            x_m: 1.5,
            y_m: 4.95,
            yaw_rad: 0.3,
            depth_m: 0.45,
            width_m: 0.45,
            height_m: 0.9,
        });
        let docking = Docking::new(scene.clone(), &RobotConfig::default());
        let mut steps = plan(&scene);
        docking.annotate(&mut steps, [0.0, 1.0, 0.0], false);
        let moved = steps[2].x_m - 1.0;
        assert!(
            (-0.1..0.0).contains(&moved) && steps[2].y_m == 5.2,
            "moved away from the chair along the table: {:?}",
            steps[2]
        );
        assert_eq!(
            steps[3].x_m, steps[2].x_m,
            "the unload's goal moved with it"
        );
        assert!(steps[2].approach_m > 0.0);
        // A chair on the standing spot: no way in.
        scene.chairs[0] = world::Chair::new(1.0, 5.2, 0.0);
        let docking = Docking::new(scene.clone(), &RobotConfig::default());
        let mut steps = plan(&scene);
        docking.annotate(&mut steps, [0.0, 1.0, 0.0], false);
        assert_eq!(steps[2].approach_m, NO_WAY_IN);
        assert_eq!(
            (steps[2].x_m, steps[2].y_m),
            (1.0, 5.2),
            "left where GROP put it"
        );
    }
}
