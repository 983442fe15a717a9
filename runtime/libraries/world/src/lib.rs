//! The dinner-table world of GROP: scene and robot files (versioned, validated), seeded scene
//! generators, base collision, the occupancy grid with an any-angle planner, overhead rendering
//! and the view/crop geometry every other crate shares.
//!
//! ```no_run
//! use world::{RobotConfig, Scene, view::{self, Side}, nav::OccupancyGrid};
//! let scene = world::generate::training_scenes(7, 10, 10).remove(0);
//! let robot = RobotConfig::default();
//! let target = scene.targets[0];
//! // What the FCN sees: the 64 x 32 near crop of the ceiling camera's view over the target.
//! let crop: [u8; 2048] = view::render_crop(&scene, target.x_m, Side::Near);
//! // Where a base commanded to crop cell (12, 31) stands.
//! let (x, y) = view::cell_center_world(target.x_m, Side::Near, 12, 31);
//! // Travel time C from the start to there (paper eq. 3).
//! let grid = OccupancyGrid::from_scene(&scene, &robot);
//! let path = grid.plan((scene.robot_start.x_m, scene.robot_start.y_m), (x, y));
//! let cost_s = path.map(|p| p.travel_time_s(robot.speed_mps));
//! # let _ = (crop, cost_s);
//! ```
//!
//! File formats, conventions and the robot's dimensions: `docs/world.md`.

pub mod camera;
pub mod collision;
mod file;
pub mod generate;
pub mod geometry;
pub mod lidar;
pub mod nav;
pub mod robot;
pub mod scene;
pub mod table_settings;
pub mod view;

pub use collision::{base_clearance, base_collides};
pub use lidar::{LidarSpec, RayScene};
pub use robot::{BaseCollisionModel, BaseFootprint, RobotConfig, RobotError};
pub use scene::{Chair, InvalidField, Scene, SceneError, UnloadTarget};
pub use ur5e_kin::{ArmMount, ObstacleBox, PlaceConfig};
pub use view::{Heatmap, Side};
