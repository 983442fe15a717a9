//! The onboard processes of grop, as they run on the robot computer (and, unchanged, against
//! the HIL world): the perception and planning node (`grop-planner`: camera frame -> views cut
//! by the frame's metric header -> Psi -> GROP -> `plan/task`, `heatmaps`) and the executive
//! (`grop-executive`: a cyclic executive driving the RMP base over CAN at 50 Hz and the UR5e
//! over RTDE at 500 Hz, following the plan, reporting on `events`). Both read a deployment
//! file and the runtime clock; neither links a simulator (a test checks the dependency tree).

pub mod deployment;
pub mod docking;
pub mod executive;
pub mod localisation;
pub mod mission_log;
pub mod planner_node;
pub mod process;
pub mod tray_plan;
