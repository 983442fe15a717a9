//! UR5e kinematics: DH forward kinematics, closed-form inverse kinematics, collision primitives.

pub mod collision;
pub mod kinematics;
pub mod path;
pub mod place;

pub use collision::{ArmCollisionModel, Capsule, ObstacleBox};
pub use kinematics::{ArmFrames, JointLimits, Joints, Ur5e, wrap_to_pi};
pub use path::{JointPathError, JointPathSettings, plan_joint_path};
pub use place::{
    ArmMount, BasePose, PlaceConfig, PlaceConfigError, PlaceFailure, PlacePlan, arm_collides,
    plan_place,
};
