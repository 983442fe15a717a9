//! Arm trajectories for a chosen plan (Algorithm 1, lines 17-20 for the manipulation actions):
//! for each unloading step, the placing configuration from closed-form IK (`ur5e_kin::plan_place`)
//! and a collision-checked joint-space path to it from the carry pose (`ur5e_kin::plan_joint_path`,
//! RRT-Connect with shortcutting), at the base pose the robot stands on.

use nalgebra::Point3;
use planar::Pose2;
use ur5e_kin::{JointPathError, Joints, PlaceFailure, plan_joint_path, plan_place};
use world::generate::mix_seed;
use world::{RobotConfig, Scene};

use crate::methods::PlannedTask;
use crate::problem::TaskProblem;

/// The arm's carry pose while the base drives: upper arm and forearm straight up, wrist folded,
/// inside the base's footprint and above everything on the floor.
pub const CARRY_JOINTS: Joints = [
    0.0,
    -std::f64::consts::FRAC_PI_2,
    0.0,
    -std::f64::consts::FRAC_PI_2,
    0.0,
    0.0,
];

/// The arm motion of one unloading step.
#[derive(Debug, Clone, PartialEq)]
pub struct UnloadMotion {
    /// The object.
    pub object: usize,
    /// Where the base stands.
    pub base: Pose2,
    /// Placing configuration (rad).
    pub place_joints: Joints,
    /// Joint path from the carry pose to `place_joints`, both included.
    pub path: Vec<Joints>,
}

/// Why an unloading step has no arm motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ArmPlanError {
    /// No placing configuration from this base pose.
    #[error("object {object}: no placing configuration: {failure}")]
    Place {
        /// The object.
        object: usize,
        /// Why.
        failure: PlaceFailure,
    },
    /// A placing configuration exists but no collision-free path reaches it.
    #[error("object {object}: no joint path: {error}")]
    Path {
        /// The object.
        object: usize,
        /// Why.
        error: JointPathError,
    },
}

/// Plans the arm motion for placing `object` at `target` from `base`, starting at `start`.
pub fn plan_unload_motion(
    scene: &Scene,
    robot: &RobotConfig,
    object: usize,
    base: Pose2,
    target: [f64; 3],
    start: &Joints,
    seed: u64,
) -> Result<UnloadMotion, ArmPlanError> {
    let obstacles = scene.obstacle_boxes(robot, base);
    let goal = Point3::new(target[0], target[1], target[2]);
    let place = plan_place(&robot.place, base, goal, &obstacles)
        .map_err(|failure| ArmPlanError::Place { object, failure })?;
    let path = plan_joint_path(&robot.place, base, start, &place.joints, &obstacles, seed)
        .map_err(|error| ArmPlanError::Path { object, error })?;
    Ok(UnloadMotion {
        object,
        base,
        place_joints: place.joints,
        path,
    })
}

/// Arm motions for every unloading step of a planned task, with the base at each commanded goal
/// (on the robot, call [`plan_unload_motion`] again with the realised pose after driving). One
/// result per step, in plan order; a failed step does not stop the others.
pub fn arm_trajectories(
    scene: &Scene,
    robot: &RobotConfig,
    problem: &TaskProblem,
    planned: &PlannedTask,
    seed: u64,
) -> Vec<Result<UnloadMotion, ArmPlanError>> {
    planned
        .plan
        .unloads
        .iter()
        .enumerate()
        .map(|(k, step)| {
            let goal = planned.goal_of(step);
            let base = Pose2 {
                x_m: goal.xy.0,
                y_m: goal.xy.1,
                yaw_rad: goal.yaw_rad,
            };
            let target = problem.location(step.object, step.side).target;
            plan_unload_motion(
                scene,
                robot,
                step.object,
                base,
                target,
                &CARRY_JOINTS,
                mix_seed(seed, 0x0061_726d, k as u64),
            )
        })
        .collect()
}
