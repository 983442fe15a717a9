//! What one update of the mission core reads ([`CycleInputs`]) and writes ([`CycleOutputs`]):
//! plain values and borrowed slices of the shell's preallocated buffers, nothing that
//! allocates.

use std::time::Duration;

use grop_ipc::{BasePoseMsg, EventMsg, LoadRequestMsg, ReplanRequestMsg, TaskPlanMsg};
use motion_control::Twist;
use rmp_base::{BaseError, BaseMode, Odometry, Tick};
use ur5e_kin::Joints;

use super::unload::{ArmFault, SkillStatus};
use super::worker::{Answer, Job};
use super::{AbortReason, ArmSnapshot};

/// Most events one update emits (an abort emits two; a cycle rarely more than three).
pub const MAX_EVENTS_PER_CYCLE: usize = 16;

/// What the base reported, as the shell read it before the update.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BaseReading {
    /// Dead-reckoned pose and measured velocity.
    pub odometry: Odometry,
    /// Start-up done and in tractor mode.
    pub driving: bool,
}

/// What the collision monitor did with the last velocity (the shell runs it between the core
/// and the base driver).
pub use motion_control::collision::Action as MonitorAction;
/// Which shapes the collision monitor uses (the core asks for the docking shape on the last
/// metres to a standing spot).
pub use motion_control::collision::MonitorMode;

/// Everything one update reads. Slices and references point into the shell's preallocated
/// buffers.
#[derive(Debug, Clone, Copy)]
pub struct CycleInputs<'a> {
    /// Runtime clock time of the cycle.
    pub now: Duration,
    /// This cycle runs the base loop (every `base_every`-th minor cycle).
    pub base_cycle: bool,
    /// The base's reading (odometry as of the last tick).
    pub base: BaseReading,
    /// The result of the base driver's last tick, given once, in the cycle after the tick.
    pub base_tick: Option<&'a Result<Tick, BaseError>>,
    /// The arm's state read this cycle.
    pub arm: Result<ArmSnapshot, ArmFault>,
    /// The result of the arm skill in flight (a poll, or a refused start), if one is.
    pub skill: Option<Result<SkillStatus, ArmFault>>,
    /// Pose fixes received since the last base cycle.
    pub fixes: &'a [BasePoseMsg],
    /// Plans received since the last cycle (the shell reads them every cycle; the core takes
    /// one on an arm cycle too and asks for its first path at once).
    pub plans: &'a [TaskPlanMsg],
    /// Planner heartbeats received since the last base cycle.
    pub planner_heartbeats: u32,
    /// The planning worker's answer, if one came.
    pub answer: Option<&'a Answer>,
    /// Shutdown asked (a signal).
    pub shutdown: bool,
    /// The runtime clock is lost (the HIL world ended).
    pub clock_lost: bool,
    /// What the collision monitor did on the last base cycle.
    pub monitor: MonitorAction,
    /// The velocity the shell last sent to the base (after the collision monitor).
    pub sent: Twist,
    /// A scan-to-map alignment that came in: the base pose it found and the odometry pose the
    /// scan was taken at.
    pub aligned: Option<(planar::Pose2, planar::Pose2)>,
    /// The operator's enable (the safety work makes start-up wait for it).
    pub operator_enable: bool,
    /// What the range sensor sees now: the collision monitor's points (base frame, moved with
    /// the odometry since the revolution), `None` without a sensor. The core checks a docking
    /// line against it before driving in.
    pub scan: Option<&'a motion_control::collision::Obstacles>,
}

impl<'a> CycleInputs<'a> {
    /// Inputs at `now` with nothing received: an arm that reads a default state, no skill, no
    /// fixes, no plans, no heartbeats. Tests and the shell fill in what they have.
    pub fn quiet(now: Duration) -> Self {
        Self {
            now,
            base_cycle: true,
            base: BaseReading::default(),
            base_tick: None,
            arm: Ok(ArmSnapshot::default()),
            skill: None,
            fixes: &[],
            plans: &[],
            planner_heartbeats: 0,
            answer: None,
            shutdown: false,
            clock_lost: false,
            monitor: MonitorAction::Clear,
            sent: Twist::ZERO,
            aligned: None,
            operator_enable: true,
            scan: None,
        }
    }
}

/// The one arm command of a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum ArmCommand {
    /// Nothing new.
    #[default]
    None,
    /// Start a joint move.
    MoveJoints(Joints),
    /// Start opening (`false`) or closing (`true`) the gripper.
    Gripper(bool),
    /// Stop any motion.
    Stop,
}

/// Everything one update decided. The shell clears it ([`CycleOutputs::clear`]) before each
/// update; nothing in it allocates.
#[derive(Debug, Clone)]
pub struct CycleOutputs {
    /// The base velocity (the one velocity of the cycle; written to the driver on base cycles,
    /// through the collision monitor).
    pub velocity: Twist,
    /// The collision monitor's shapes for that velocity.
    pub monitor_mode: MonitorMode,
    /// A base mode to request.
    pub base_mode: Option<BaseMode>,
    /// Re-arm the base driver (the explicit acknowledgement at mission start, and the
    /// operator's enable releasing a latched safety stop).
    pub rearm_base: bool,
    /// A latched safety stop was taken (an abort for a safety cause, a UR safety stop): the
    /// base ramps to zero at the emergency deceleration until re-armed. Operational holds
    /// (monitor stops, stale scans, no localisation, waiting for a plan) do not set it.
    pub safety_stop: bool,
    /// The arm command.
    pub arm: ArmCommand,
    /// A job for the planning worker.
    pub job: Option<Job>,
    /// A plan request to publish.
    pub request: Option<ReplanRequestMsg>,
    /// A load request to publish (`load/request`: the objects the station is to put on the
    /// tray).
    pub load_request: Option<LoadRequestMsg>,
    /// Events to publish, in order.
    pub events: heapless::Vec<EventMsg, MAX_EVENTS_PER_CYCLE>,
    /// Events that did not fit (counted, logged).
    pub events_dropped: u32,
    /// Set in the cycle the mission aborted.
    pub abort: Option<AbortReason>,
}

impl Default for CycleOutputs {
    fn default() -> Self {
        Self {
            velocity: Twist::ZERO,
            monitor_mode: MonitorMode::Normal,
            base_mode: None,
            rearm_base: false,
            safety_stop: false,
            arm: ArmCommand::None,
            job: None,
            request: None,
            load_request: None,
            events: heapless::Vec::new(),
            events_dropped: 0,
            abort: None,
        }
    }
}

impl CycleOutputs {
    /// Empties it for the next update.
    pub fn clear(&mut self) {
        self.velocity = Twist::ZERO;
        self.monitor_mode = MonitorMode::Normal;
        self.base_mode = None;
        self.rearm_base = false;
        self.safety_stop = false;
        self.arm = ArmCommand::None;
        self.job = None;
        self.request = None;
        self.load_request = None;
        self.events.clear();
        self.events_dropped = 0;
        self.abort = None;
    }
}
