//! UR5e kinematics and arm planning for the grop mobile manipulator.
//!
//! - [`Ur5e`]: the published UR5e DH table and joint limits; [`Ur5e::forward`] (arm base frame ->
//!   tool flange) and the closed-form [`Ur5e::inverse`] (all up to 8 solutions within limits).
//! - [`ArmMount`], [`PlaceConfig`], [`world_from_base`]: where the arm stands on the mobile base
//!   (a base pose is a [`planar::Pose2`]), the
//!   Robotiq 2F-140 tool centre point, and the tool-down tolerance.
//! - [`plan_place`]: can the arm put the held object at its goal from this base pose, tool down,
//!   clear of the [`ObstacleBox`]es? (the per-trial test of the paper's data collection,
//!   section IV-B). Allocation-free, a few microseconds per call.
//! - [`plan_joint_path`]: RRT-Connect plus shortcutting between two configurations.
//!
//! Frames and defaults are documented in `docs/kinematics.md`.
//!
//! ```
//! use core::f64::consts::FRAC_PI_2;
//! use nalgebra::Point3;
//! use planar::Pose2;
//! use ur5e_kin::{ObstacleBox, PlaceConfig, plan_place, plan_joint_path};
//!
//! let cfg = PlaceConfig::default();
//! // Banquet table: centre line y = 6, 0.4 m deep, top at 1.0 m; object goal 1.3 m high.
//! let table = ObstacleBox::from_min_max(Point3::new(-1.5, 5.8, 0.0), Point3::new(1.5, 6.2, 1.0));
//! let base = Pose2 { x_m: 0.0, y_m: 5.3, yaw_rad: FRAC_PI_2 }; // facing the table
//! let plan = plan_place(&cfg, base, Point3::new(0.0, 6.0, 1.3), &[table])
//!     .expect("0.7 m from the centre line is within reach");
//! assert!(plan.tool_tilt_rad <= cfg.down_tolerance_rad);
//!
//! // From a folded pose above the base to the placement, around the table.
//! let folded = [0.0, -2.0, 2.2, -1.8, -FRAC_PI_2, 0.0];
//! let path = plan_joint_path(&cfg, base, &folded, &plan.joints, &[table], 42).expect("path");
//! assert_eq!(path.last(), Some(&plan.joints));
//! ```

#[doc(hidden)]
pub mod bench_scene;
pub mod collision;
pub mod kinematics;
pub mod path;
pub mod place;

pub use collision::{ArmCollisionModel, Capsule, ObstacleBox};
pub use kinematics::{ArmFrames, JointLimits, Joints, Ur5e};
pub use path::{JointPathError, JointPathSettings, plan_joint_path};
pub use place::{
    ArmMount, PlaceConfig, PlaceConfigError, PlaceFailure, PlacePlan, arm_collides, plan_place,
    world_from_base,
};
