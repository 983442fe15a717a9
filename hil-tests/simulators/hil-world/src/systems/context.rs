//! What the systems share: the loop's [`Flow`], the [`System`] trait and the context.

use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Point3};
use planar::Pose2;

use crate::injector::Injector;
use crate::report::WorldReport;
use crate::{World, WorldConfig};

/// What a system tells the loop after its step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Flow {
    /// On to the next system.
    Next,
    /// The rest of this step is skipped and the clock not moved (waiting to start).
    Wait,
    /// The run is over.
    Stop,
}

/// One system of the world's step.
pub(crate) trait System {
    /// The system's name (the table in the module docs).
    #[allow(dead_code, reason = "read by the order test and when debugging")]
    fn name(&self) -> &'static str;
    /// One step at `ctx.now`.
    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow;
}

/// The devices' state at this step, as the `Readings` system (and `Base` for the pose) read
/// them; the systems after them use these.
pub(crate) struct Reading {
    /// The true base pose in the world.
    pub(crate) pose: Pose2,
    /// The base's speed and yaw rate.
    pub(crate) v: f32,
    pub(crate) w: f32,
    /// The planar speed magnitude (speed plus yaw rate scaled to the footprint).
    pub(crate) speed: f64,
    /// The base's frame in the world.
    pub(crate) world_from_base: Isometry3<f64>,
    /// The arm's state.
    pub(crate) snap: sim_ur5e::robot::Snapshot,
    /// The tool point in the world.
    pub(crate) tcp: Point3<f64>,
}

/// The mission's state that several systems share.
#[derive(Default)]
pub(crate) struct Mission {
    /// Everyone joined.
    pub(crate) joined: bool,
    /// When the mission clock started.
    pub(crate) start: Option<Duration>,
    /// When the mission ended (the executive said so, or died).
    pub(crate) ended_at: Option<Duration>,
    /// The newest task plan's steps.
    pub(crate) latest_plan: Vec<grop_ipc::TaskStep>,
    /// How long the base has stood still.
    pub(crate) still_s: f64,
    /// The executive said a goal was reached; the leg is not recorded yet.
    pub(crate) goal_reached_pending: bool,
    /// The operator's enable, asked for and due then.
    pub(crate) enable_due: Option<Duration>,
    /// Something touched furniture during this leg.
    pub(crate) collided_this_leg: bool,
    /// Base and arm touch furniture now (as of the last contact check).
    pub(crate) in_collision: [bool; 2],
    /// The base was stalled against furniture since the last contact check.
    pub(crate) blocked_since_check: bool,
    /// Timing: the first replan request, plan and motion (s).
    pub(crate) first_request: Option<f64>,
    pub(crate) first_plan: Option<f64>,
    pub(crate) first_motion: Option<f64>,
    /// Wall time spent stepping.
    pub(crate) step_wall: Duration,
}

/// What the systems share.
pub(crate) struct Ctx<'w> {
    /// The world: devices, ports, objects, fix simulator.
    pub(crate) world: &'w mut World,
    /// The settings with the running truth (chairs move; the world's own copy keeps the start).
    pub(crate) cfg: WorldConfig,
    /// The report being written.
    pub(crate) report: WorldReport,
    /// The fault injector's state.
    pub(crate) injector: Injector,
    /// The mission's shared state.
    pub(crate) mission: Mission,
    /// This step's readings.
    pub(crate) reading: Reading,
    /// The simulated time of this step.
    pub(crate) now: Duration,
    /// The step.
    pub(crate) dt: Duration,
    /// When the run started (wall).
    pub(crate) wall_start: Instant,
    /// When this step's work started (wall).
    pub(crate) work_started: Instant,
}
