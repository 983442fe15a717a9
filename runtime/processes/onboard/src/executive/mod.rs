//! The executive: a cyclic executive in its own process that runs the plan on the robot.
//!
//! It is split as ros2_control splits a controller manager: a pure mission core and an I/O
//! shell. [`MissionCore::update`] ([`mission`], with the leg phases in [`legs`]) takes
//! everything it reads as [`CycleInputs`] and writes everything it decides into
//! [`CycleOutputs`]: one velocity, one arm command, a worker job, a plan request, events, the
//! abort. It opens no port and calls no device, so its safety reactions are tested with plain
//! values. [`Executive`] ([`shell`]) is the process around it: each cycle it reads the devices
//! ([`BaseDevice`], [`ArmDevice`]) and the topics, calls the core once, and writes the outputs.
//!
//! One thread, a fixed minor cycle (2 ms, the UR5e's RTDE period) on absolute deadlines of the
//! runtime clock ([`grop_clock::Clock`]): every cycle the arm is read and its skill polled;
//! every `base_every`-th cycle (20 ms, 50 Hz) the base loop runs: localisation fixes are fused
//! with odometry, the mission advances, and the RMP driver ticks once over its `CanBus`.
//! Everything the loop needs is allocated before the first cycle; planning work that allocates
//! (base paths, arm motions) runs in a worker thread behind bounded channels ([`worker`]).
//! Overruns (a cycle that starts after its deadline) are counted and reported in heartbeats and
//! `base/state`.
//!
//! The mission: ask the planning node for a plan (`plan/request`), then per step: drive to the
//! goal (path from the navigation planner, pure pursuit within the robot file's limits, final
//! heading aligned to the table, settle), load at the station, or unload with inverse
//! kinematics solved at the pose the table-relative fix measured ([`unload`]). After a failed
//! unload it asks for a new plan for what is left: how (or whether) to retry is the planner's
//! decision. Every step is reported on `events`.
//!
//! Safety (DESIGN.md): a lost base (no feedback), a base fault or overspeed, a lost arm link, an
//! arm stop, a dead planner (heartbeats missing) or a lost clock abort the mission: the base is
//! commanded to zero (the driver ramps at its deceleration limit) and the arm is stopped. Aborted
//! is final: motion resumes only after the executive is restarted (re-armed) by an operator. The
//! RMP driver latches the same way on its own (a lost link, a fault or an overspeed disarm it);
//! the executive re-arms it once, at mission start, and never after a fault. Stale
//! localisation holds the base at zero until fixes return. If this process dies, the base's own
//! 0.5 s loss-of-command timeout and the arm controller's RTDE watchdog stop both.

pub mod arm_io;
pub mod base;
pub mod cycle;
pub mod inputs;
pub mod io_worker;
pub mod legs;
pub mod mission;
pub mod motion_watch;
pub mod plan_check;
pub mod range;
pub mod safety;
pub mod scan_match;
pub mod shell;
pub mod unload;
pub mod ur5e_arm;
pub mod worker;

use std::time::Duration;

use motion_control::follower::FollowerConfig;
use ur5e_kin::Joints;
use world::RobotConfig;

use crate::localisation::LocaliserConfig;
use unload::{ArmFault, ArmPort};

pub use base::BaseDevice;
pub use cycle::{ArmCommand, BaseReading, CycleInputs, CycleOutputs, MonitorAction, MonitorMode};
pub use mission::MissionCore;
pub use shell::{Executive, ExecutivePorts, RmpExecutive, rmp_config_for};

/// What the executive needs of the arm besides the unload skills.
pub trait ArmDevice: ArmPort {
    /// Reads the newest controller state at `now` (non-blocking); an error means the arm can
    /// no longer be trusted to move.
    fn update(&mut self, now: Duration) -> Result<ArmSnapshot, ArmFault>;
    /// Stops any motion (best effort; the controller's watchdog is the last line).
    fn stop(&mut self, now: Duration);
}

/// The arm state the executive publishes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ArmSnapshot {
    /// Joint positions, rad.
    pub q_rad: Joints,
    /// Joint speeds, rad/s.
    pub qd_radps: Joints,
    /// Flange pose in the arm base frame (x, y, z, rotation vector).
    pub flange_pose: [f64; 6],
    /// A program runs on the controller.
    pub program_running: bool,
    /// Robot mode code.
    pub robot_mode: i32,
    /// Protective stop.
    pub protective_stop: bool,
    /// Emergency stop.
    pub emergency_stop: bool,
    /// UR `safety_mode` (`ur5e::dashboard::SafetyMode` codes, 1 normal; 0: not reported).
    pub safety_mode: i32,
}

/// Settings of the executive (the robot file's limits enter through [`ExecutiveConfig::for_robot`]).
#[derive(Debug, Clone)]
pub struct ExecutiveConfig {
    /// Minor cycle (the arm's cycle). 2 ms.
    pub cycle: Duration,
    /// The base loop runs every this many minor cycles (10: 50 Hz).
    pub base_every: u32,
    /// Path follower (speed, yaw rate and deceleration from the robot file).
    pub follower: FollowerConfig,
    /// Heading tolerance of the final alignment, rad.
    pub yaw_tolerance_rad: f64,
    /// Proportional gain of the final alignment, 1/s.
    pub align_gain: f64,
    /// Standing still after arriving before the step counts as reached.
    pub settle: Duration,
    /// How long loading at the station takes (people put objects on the tray).
    pub load_wait: Duration,
    /// A table-relative fix must arrive within this after the base stopped at the table.
    pub table_fix_wait: Duration,
    /// A leg may take this factor times its planned travel time plus `leg_slack`.
    pub leg_time_factor: f64,
    /// See `leg_time_factor`.
    pub leg_slack: Duration,
    /// Planner heartbeats missing this long: the planner is dead.
    pub planner_timeout: Duration,
    /// A plan request without an answer is sent again after this.
    pub plan_request_retry: Duration,
    /// After the localisation jumps (a fix far from the estimate), the base is commanded to
    /// stand still (through the deceleration ramp) this long, so that it never steers hard on
    /// one wrong fix (or on the jump back); then the leg goes on from the estimate.
    pub jump_hold: Duration,
    /// Heartbeat period.
    pub heartbeat_period: Duration,
    /// A fix stamped later than now by more than this (one fix period) is refused: a stamp
    /// from the future would make every later real fix look older, and the estimate would
    /// never go stale.
    pub fix_future_tolerance: Duration,
    /// Localisation filter.
    pub localiser: LocaliserConfig,
    /// Tray slots, base frame (m).
    pub tray_slots: Vec<[f64; 3]>,
    /// Clearance kept from furniture by base paths where the map allows (m).
    pub path_clearance_m: f64,
    /// The robot file (limits, footprint, arm mount).
    pub robot: RobotConfig,
    /// A leg the collision monitor holds (stop zone, stale scan) this long is given up and
    /// planned again from where the base stands.
    pub blocked_timeout: Duration,
    /// The same on the docking stretch (a chair moved into the standing spot).
    pub docking_blocked_timeout: Duration,
    /// Motion sent to the base with none measured for this long is a stall: the leg stops.
    pub stall_after: Duration,
    /// The arm may run in UR's reduced safety mode (reduced limits in force); otherwise reduced
    /// mode pauses the mission like a safeguard stop.
    pub allow_reduced_mode: bool,
    /// The node allowed to publish each command input (docs/security.md).
    pub inputs: inputs::InputSources,
    /// Replays only: the RMP driver takes the stored limits the base echoes at start-up as
    /// verified and writes none ([`rmp_base::RmpBaseConfig::adopt_stored_limits`]), as the
    /// driver did before it kept the robot's limits in the base. Never on a robot.
    pub adopt_base_limits: bool,
}

impl ExecutiveConfig {
    /// Settings for `robot` (speed, acceleration and yaw-rate limits from its file).
    pub fn for_robot(robot: &RobotConfig) -> Self {
        Self {
            cycle: Duration::from_millis(2),
            base_every: 10,
            follower: FollowerConfig {
                lookahead_m: 0.35,
                cruise_speed_mps: robot.speed_mps as f32,
                max_yaw_rate_radps: robot.yaw_rate_radps as f32,
                stop_decel_mps2: (0.8 * robot.accel_mps2) as f32,
                goal_tolerance_m: 0.02,
                turn_in_place_above_rad: 0.8,
            },
            yaw_tolerance_rad: 0.008,
            align_gain: 2.0,
            settle: Duration::from_millis(400),
            load_wait: Duration::from_secs(3),
            table_fix_wait: Duration::from_secs(2),
            leg_time_factor: 3.0,
            leg_slack: Duration::from_secs(20),
            planner_timeout: Duration::from_millis(500),
            plan_request_retry: Duration::from_secs(1),
            jump_hold: Duration::from_secs(1),
            heartbeat_period: Duration::from_millis(100),
            fix_future_tolerance: Duration::from_millis(100),
            localiser: LocaliserConfig::default(),
            tray_slots: unload::default_tray_slots().to_vec(),
            path_clearance_m: 0.15,
            robot: robot.clone(),
            blocked_timeout: Duration::from_secs(8),
            docking_blocked_timeout: Duration::from_secs(3),
            stall_after: Duration::from_secs(1),
            allow_reduced_mode: true,
            inputs: inputs::InputSources::default(),
            adopt_base_limits: false,
        }
    }
}

/// Why the executive could not start.
#[derive(Debug, thiserror::Error)]
pub enum ExecutiveError {
    /// A topic could not be opened.
    #[error("executive IPC: {0}")]
    Ipc(String),
    /// The base driver refused its configuration.
    #[error("base driver configuration: {0}")]
    BaseConfig(String),
    /// The tray cannot be reached by the arm.
    #[error("tray: {0}")]
    Tray(String),
    /// The path worker could not start.
    #[error("path worker: {0}")]
    Worker(std::io::Error),
    /// The robot file's `carry_capacity` exceeds the tray's slots: plans would load objects the
    /// tray cannot hold.
    #[error(
        "robot file: carry_capacity = {carry_capacity} exceeds the {tray_slots} tray slots of the executive"
    )]
    CarryCapacity {
        /// The robot file's `carry_capacity`.
        carry_capacity: u32,
        /// Usable tray slots (`ExecutiveConfig::tray_slots`, at most [`MAX_TRAY_SLOTS`]).
        tray_slots: usize,
    },
}

/// Most tray slots the executive tracks (the messages' tray).
pub const MAX_TRAY_SLOTS: usize = grop_ipc::MAX_TRAY_SLOTS;

/// How the mission ended (or is going).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MissionState {
    /// Waiting for the base, the localiser and a plan.
    Starting,
    /// Running a plan.
    Running,
    /// Every step done.
    Finished,
    /// Stopped for safety; a new mission needs a restart and the operator's enable.
    Aborted(AbortReason),
}

/// Why a mission was aborted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AbortReason {
    /// The base stopped answering on CAN.
    BaseLinkLost,
    /// The base reported a fault, or moved faster than commanded.
    BaseFault,
    /// Another host sends commands on the base's bus.
    SecondCommander,
    /// The arm link is gone.
    ArmLinkLost,
    /// The arm is in a protective or emergency stop.
    ArmStopped,
    /// The arm's safety mode is one that ends a mission (recovery, violation, fault, ...), or
    /// its robot mode left running.
    ArmUnsafe,
    /// The base left tractor mode without being asked (a mode drop with no fault word).
    BaseModeLost,
    /// The planning node died.
    PlannerLost,
    /// The clock is lost (the HIL world ended).
    ClockLost,
    /// Asked to stop (signal).
    Shutdown,
    /// Legs kept failing: no route from where the base stands.
    Stuck,
    /// The planner kept answering with plans the executive refuses (the tray, the robot's
    /// limits, a malformed plan): [`PLANS_REFUSED_LIMIT`] in a row.
    PlansRefused,
}

/// Plans refused in a row before the mission is given up.
pub const PLANS_REFUSED_LIMIT: u32 = 5;

/// Counters for reports.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ExecutiveStats {
    /// Minor cycles run.
    pub cycles: u64,
    /// Cycles that started after their deadline.
    pub overruns: u64,
    /// Unloads the executive saw succeed.
    pub unloads_ok: u32,
    /// Unloads that failed.
    pub unloads_failed: u32,
    /// Plans received.
    pub plans: u32,
    /// Messages published (iceoryx2 0.10 allocates one small reference-counted block per
    /// loaned sample, upstream: the allocation test accounts for exactly these).
    pub published: u64,
    /// Command inputs refused (not from the deployment's publisher, or out of sequence).
    pub inputs_refused: u64,
}
