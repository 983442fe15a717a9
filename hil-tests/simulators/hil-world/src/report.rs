//! The world's account of a mission: the truth (where the base drove, what touched what, where
//! each object ended), what the onboard processes said (events, plans), and what happened when
//! something died. Written as JSON (`--report FILE`); `grop demo` and `grop hil` read it.

use serde::{Deserialize, Serialize};

use crate::objects::TrackedObject;

/// How the mission ended, as the world saw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MissionEnd {
    /// The executive reported the plan finished.
    Finished,
    /// The executive reported an abort.
    Aborted,
    /// The executive process died.
    ExecutiveDied,
    /// Simulated time ran out.
    TimedOut,
    /// The onboard processes never joined.
    NeverStarted,
}

/// A contact of the robot with furniture.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CollisionRecord {
    /// Simulated time, s.
    pub t_s: f64,
    /// `base` or `arm`.
    pub part: Part,
    /// Base pose then (x, y, yaw).
    pub base: [f64; 3],
    /// Arm joints then (rad).
    #[serde(default)]
    pub q: [f64; 6],
    /// Centre of the obstacle box touched (world, m), when known.
    #[serde(default)]
    pub obstacle: Option<[f64; 3]>,
}

/// Which part touched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Part {
    /// The base footprint.
    Base,
    /// An arm link.
    Arm,
}

/// A leg that ended at a plan's navigation goal: commanded vs realised.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LegRecord {
    /// When the base came to rest, s.
    pub t_s: f64,
    /// The goal the plan commanded (x, y, yaw).
    pub commanded: [f64; 3],
    /// Where the base truly stopped (x, y, yaw).
    pub realised: [f64; 3],
    /// The localisation bias drawn for this leg (x, y).
    pub fix_bias: [f64; 2],
}

/// An event of an onboard process.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EventRecord {
    /// Simulated time, s.
    pub t_s: f64,
    /// Kind name.
    pub kind: String,
    /// Plan id.
    pub plan_id: u64,
    /// Step index.
    pub step: u32,
    /// Text.
    pub detail: String,
}

/// A plan as published.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanRecord {
    /// Simulated time of publication, s.
    pub t_s: f64,
    /// Plan id.
    pub plan_id: u64,
    /// Request answered.
    pub answers_request: u64,
    /// Wall-clock decision time (cut + Psi + GROP), us.
    pub decision_us: u64,
    /// U, F, C.
    pub utility: f64,
    /// F(p).
    pub feasibility: f64,
    /// C(p), s.
    pub cost_s: f64,
    /// Unload steps: (object, side, goal x, goal y, F).
    pub unloads: Vec<(u32, i32, f64, f64, f64)>,
}

/// What happened after a process died.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeathRecord {
    /// Participant name.
    pub name: String,
    /// Its pid.
    pub pid: u32,
    /// Simulated time the clock noticed, s.
    pub t_s: f64,
    /// Base speed then, m/s.
    pub base_speed_then_mps: f64,
    /// First time after it that the base stood still (|v| < 1 cm/s), s.
    pub base_stopped_at_s: Option<f64>,
    /// Largest arm joint speed then, rad/s.
    pub arm_speed_then_radps: f64,
    /// First time after it that the arm stood still, s.
    pub arm_stopped_at_s: Option<f64>,
}

/// Timing of the closed loop.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct LoopTiming {
    /// Simulated time of the mission, s.
    pub sim_time_s: f64,
    /// Wall time of the loop, s.
    pub wall_time_s: f64,
    /// World steps.
    pub steps: u64,
    /// Camera frames published.
    pub frames: u64,
    /// Mean wall time of a world step (its own work, without waiting for participants), us.
    pub world_step_us: f64,
    /// Simulated time from the first plan request to the first plan, s.
    pub request_to_plan_s: Option<f64>,
    /// Simulated time from the first plan to the base's first motion, s.
    pub plan_to_motion_s: Option<f64>,
}

/// The world's report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorldReport {
    /// Scene name.
    pub scene: String,
    /// Seed of the world's noise.
    pub seed: u64,
    /// How it ended.
    pub end: MissionEnd,
    /// Objects placed with no contact at all during their leg (strict).
    pub placed: usize,
    /// Objects placed by the paper's end-state criterion (free base and arm at release, contacts
    /// on the way allowed): what the trial simulator and `grop eval` count.
    #[serde(default)]
    pub placed_end_state: usize,
    /// The objects.
    pub objects: Vec<TrackedObject>,
    /// Contacts with furniture.
    pub collisions: Vec<CollisionRecord>,
    /// Legs that ended at a plan goal.
    pub legs: Vec<LegRecord>,
    /// True base trajectory, (t, x, y, yaw) every 0.2 s.
    pub trajectory: Vec<[f64; 4]>,
    /// Events of the onboard processes.
    pub events: Vec<EventRecord>,
    /// Plans.
    pub plans: Vec<PlanRecord>,
    /// Processes that died.
    pub deaths: Vec<DeathRecord>,
    /// Timing.
    pub timing: LoopTiming,
    /// The fault injected, if any, and what followed.
    #[serde(default)]
    pub fault: Option<crate::faults::FaultRecord>,
    /// The motion commands the base received over the mission.
    #[serde(default)]
    pub commands: crate::faults::CommandMonitor,
    /// Fastest the base truly drove (m/s) and turned (rad/s).
    #[serde(default)]
    pub max_base_speed: (f64, f64),
    /// The closest call: the smallest gap between the base's footprint and any table, chair
    /// or wall during the mission (m; 0 in contact), and the base pose then (checked every
    /// 10 ms; `None` before the mission started).
    #[serde(default)]
    pub min_base_clearance: Option<(f64, [f64; 3])>,
    /// Times the world held the base back at furniture (drives stalled).
    #[serde(default)]
    pub base_blocks: u64,
    /// Objects never attempted: still at the loading station when the mission ended (the
    /// planner could not plan them, or the mission ended first).
    #[serde(default)]
    pub not_attempted: Vec<usize>,
}
