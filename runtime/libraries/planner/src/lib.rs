//! Task planner, GROP and baselines: the symbolic domain of the paper's section III and its plan
//! enumeration / exact optimiser ([`task`]), the feasibility evaluator trait `Psi`
//! ([`feasibility`]), navigation costs ([`costs`]), GROP (Algorithm 1) and the four baselines behind
//! one [`methods::TaskMotionPlanner`] interface, and arm trajectories for the chosen plan ([`arm`]).
//!
//! ```no_run
//! use planner::costs::GridTravelTime;
//! use planner::feasibility::FcnEvaluator;
//! use planner::methods::{MethodKind, Planner, PlannerConfig, TaskMotionPlanner};
//! use planner::problem::TaskProblem;
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let scene = world::generate::evaluation_scene(1, 20, 3);
//! let robot = world::RobotConfig::default();
//! let mut psi = FcnEvaluator::load(std::path::Path::new("models/psi-fcn.onnx"))?;
//! let targets: Vec<[f64; 3]> = scene.targets.iter().map(|t| t.as_array()).collect();
//! // Six crops through the FCN, free cells marked.
//! let problem = TaskProblem::from_world(&scene, &robot, &targets, &mut psi)?;
//! let grid = world::nav::OccupancyGrid::from_scene(&scene, &robot);
//! let mut travel = GridTravelTime::new(&grid, robot.speed_mps);
//! let mut grop = Planner::new(MethodKind::Grop, PlannerConfig::for_robot(&robot));
//! let decision = grop.plan(&problem, &mut travel, 42)?;
//! println!("{}", decision.explain(5)); // F, C, U per location and the top plans
//! # Ok(()) }
//! ```
pub mod arm;
pub mod config;
pub mod costs;
pub mod feasibility;
pub mod grop_plus;
pub mod methods;
pub mod multi_trip;
pub mod problem;
pub mod task;
pub mod trip_methods;
