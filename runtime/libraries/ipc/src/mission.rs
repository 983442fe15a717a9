//! Messages of a mission between the onboard processes: the task plan with load, navigate and
//! unload steps (`plan/task`, version 2 of the plan: more steps, load steps), replan requests
//! (`plan/request`), Psi's heatmaps (`heatmaps`), localisation fixes (`base/pose`) and process
//! heartbeats (`health`). Same rules as `messages`: `#[repr(C)]`, plain data, all-zero bytes
//! valid, every count and enum checked by its accessor.

use iceoryx2::prelude::ZeroCopySend;

use crate::messages::{MessageError, ProcessRole, TableSide};

// ---------------------------------------------------------------------------------------------
// plan/task

/// Most steps one task plan carries: 36 objects (12 place settings) with a capacity of 3 need
/// 36 unloads + 36 navigations + 12 loads + 12 drives to the station = 96.
pub const MAX_TASK_STEPS: usize = 128;

/// Most objects a task has (bit masks are `u64`).
pub const MAX_TASK_OBJECTS: usize = 64;

/// What a step of a task plan does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum TaskStepKind {
    /// Drive the base to (`x_m`, `y_m`) and turn to `yaw_rad`.
    Navigate = 1,
    /// At the loading station: take the objects in `load_mask` onto the tray.
    Load = 2,
    /// At the table: unload `object_index` onto `target_m` from `side`.
    Unload = 3,
}

impl TaskStepKind {
    fn from_wire(value: u32) -> Result<Self, MessageError> {
        Ok(match value {
            1 => Self::Navigate,
            2 => Self::Load,
            3 => Self::Unload,
            _ => {
                return Err(MessageError::UnknownEnumValue {
                    message: "TaskStep",
                    field: "kind",
                    value,
                });
            }
        })
    }
}

/// One step of a task plan.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::TaskStep/v3")]
pub struct TaskStep {
    /// [`TaskStepKind`] as an integer; read with [`TaskStep::kind`].
    pub kind: u32,
    /// +1 near side, -1 far side (unload and the navigation before it), 0 otherwise.
    pub side: i32,
    /// Object of an unload step.
    pub object_index: u32,
    /// Unload: the tray slot its object rides in (the planner accounts for the tray: a load
    /// step puts each of its objects into the slot its unload step names); 0 otherwise.
    pub tray_slot: u32,
    /// Objects taken on board by a load step (bit i = object i).
    pub load_mask: u64,
    /// Navigation goal (or where the step happens), world x, metres.
    pub x_m: f64,
    /// Navigation goal, world y, metres.
    pub y_m: f64,
    /// Heading at the goal, radians.
    pub yaw_rad: f64,
    /// Object goal on the table (unload), world frame, metres.
    pub target_m: [f64; 3],
    /// Feasibility F of this (target, side) pair (unload), 0..=1 (eq. 4).
    pub feasibility: f64,
    /// Travel time of the leg that ends here (navigate), seconds.
    pub travel_cost_s: f64,
    /// Docking (navigate): > 0, the goal is docked: the path ends this far straight behind it
    /// (m, against `yaw_rad`), where the base turns, then drives straight in; 0, the goal is
    /// not docked; negative, a goal next to a table with no straight way in on the map (the
    /// executive fails the leg before it drives). Planned with the map by the planner node.
    pub approach_m: f64,
    /// Backing out (navigate): before the leg's path, the base backs straight out this far
    /// (m) from where it stands at a table; 0, it does not.
    pub back_out_m: f64,
}

impl TaskStep {
    /// A navigation step.
    pub fn navigate(x_m: f64, y_m: f64, yaw_rad: f64, travel_cost_s: f64) -> Self {
        let mut step = Self::zeroed(TaskStepKind::Navigate);
        step.x_m = x_m;
        step.y_m = y_m;
        step.yaw_rad = yaw_rad;
        step.travel_cost_s = travel_cost_s;
        step
    }

    /// A load step at the station (`x_m`, `y_m`).
    pub fn load(load_mask: u64, x_m: f64, y_m: f64) -> Self {
        let mut step = Self::zeroed(TaskStepKind::Load);
        step.load_mask = load_mask;
        step.x_m = x_m;
        step.y_m = y_m;
        step
    }

    /// An unload step from the base goal (`x_m`, `y_m`, `yaw_rad`).
    pub fn unload(
        object_index: u32,
        side: TableSide,
        target_m: [f64; 3],
        goal: [f64; 3],
        feasibility: f64,
    ) -> Self {
        let mut step = Self::zeroed(TaskStepKind::Unload);
        step.object_index = object_index;
        step.side = side.to_wire();
        step.target_m = target_m;
        step.x_m = goal[0];
        step.y_m = goal[1];
        step.yaw_rad = goal[2];
        step.feasibility = feasibility;
        step
    }

    fn zeroed(kind: TaskStepKind) -> Self {
        Self {
            kind: kind as u32,
            side: 0,
            object_index: 0,
            tray_slot: 0,
            load_mask: 0,
            x_m: 0.0,
            y_m: 0.0,
            yaw_rad: 0.0,
            target_m: [0.0; 3],
            feasibility: 0.0,
            travel_cost_s: 0.0,
            approach_m: 0.0,
            back_out_m: 0.0,
        }
    }

    /// The kind, checked.
    pub fn kind(&self) -> Result<TaskStepKind, MessageError> {
        TaskStepKind::from_wire(self.kind)
    }

    /// The table side of an unload (or its navigation), checked.
    pub fn side(&self) -> Result<TableSide, MessageError> {
        TableSide::from_wire(self.side, "TaskStep")
    }

    /// The object of an unload step, checked against [`MAX_TASK_OBJECTS`].
    pub fn object(&self) -> Result<usize, MessageError> {
        let index = self.object_index as usize;
        if index < MAX_TASK_OBJECTS {
            Ok(index)
        } else {
            Err(MessageError::CountTooLarge {
                message: "TaskStep",
                field: "object_index",
                count: u64::from(self.object_index),
                capacity: MAX_TASK_OBJECTS as u64,
            })
        }
    }

    /// Whether every number of the step is finite (a plan with NaN goals must not move a base).
    pub fn is_finite(&self) -> bool {
        [
            self.x_m,
            self.y_m,
            self.yaw_rad,
            self.feasibility,
            self.travel_cost_s,
            self.approach_m,
            self.back_out_m,
        ]
        .iter()
        .chain(self.target_m.iter())
        .all(|v| v.is_finite())
    }
}

/// A task plan (`plan/task`): the argmax of U(p) = R * F(p) - C(p)
/// (paper eq. 1) as the executive runs it, with load steps and room for whole table settings.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::TaskPlanMsg/v3")]
pub struct TaskPlanMsg {
    /// Plan counter; a replan gets a new id.
    pub plan_id: u64,
    /// Publication time on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// Id of the camera frame the plan was made from.
    pub source_frame_id: u64,
    /// The replan request it answers (0: the first plan of a mission).
    pub answers_request: u64,
    /// Utility U(p) = R * F(p) - C(p).
    pub utility: f64,
    /// Plan feasibility F(p).
    pub feasibility: f64,
    /// Plan cost C(p): travel time, seconds.
    pub cost_s: f64,
    /// Success reward R.
    pub reward: f64,
    /// Objects of the task.
    pub object_count: u32,
    /// Number of valid entries in `steps`; read with [`TaskPlanMsg::steps`].
    pub step_count: u32,
    /// Wall-clock time the decision took (perception + planning), microseconds, for reports.
    pub decision_us: u64,
    /// The steps; only the first `step_count` are meaningful.
    pub steps: [TaskStep; MAX_TASK_STEPS],
}

impl TaskPlanMsg {
    /// The plan's steps, after checking `step_count` and that every step is finite.
    pub fn steps(&self) -> Result<&[TaskStep], MessageError> {
        let count = self.step_count as usize;
        let steps = self.steps.get(..count).ok_or(MessageError::CountTooLarge {
            message: "TaskPlanMsg",
            field: "step_count",
            count: u64::from(self.step_count),
            capacity: MAX_TASK_STEPS as u64,
        })?;
        if let Some(bad) = steps.iter().position(|s| !s.is_finite()) {
            return Err(MessageError::NotFinite {
                message: "TaskPlanMsg",
                field: "steps",
                index: bad as u32,
            });
        }
        Ok(steps)
    }

    /// Replaces the steps; fails if there are more than [`MAX_TASK_STEPS`].
    pub fn set_steps(&mut self, steps: &[TaskStep]) -> Result<(), MessageError> {
        let slots = self
            .steps
            .get_mut(..steps.len())
            .ok_or(MessageError::CountTooLarge {
                message: "TaskPlanMsg",
                field: "steps",
                count: steps.len() as u64,
                capacity: MAX_TASK_STEPS as u64,
            })?;
        slots.copy_from_slice(steps);
        // Cannot truncate: at most MAX_TASK_STEPS.
        self.step_count = steps.len() as u32;
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// plan/request

/// Why the executive asks for a plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum ReplanReason {
    /// The mission starts: plan all objects from the start pose.
    MissionStart = 1,
    /// An unload failed: plan what is left from where the robot stands.
    UnloadFailed = 2,
    /// The scene changed (a new frame disagrees with the map).
    SceneChanged = 3,
    /// A leg could not be driven (no path, blocked).
    LegFailed = 4,
}

impl ReplanReason {
    fn from_wire(value: u32) -> Result<Self, MessageError> {
        Ok(match value {
            1 => Self::MissionStart,
            2 => Self::UnloadFailed,
            3 => Self::SceneChanged,
            4 => Self::LegFailed,
            _ => {
                return Err(MessageError::UnknownEnumValue {
                    message: "ReplanRequestMsg",
                    field: "reason",
                    value,
                });
            }
        })
    }
}

/// The executive asks the planning node for a plan (`plan/request`).
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::ReplanRequestMsg/v2")]
pub struct ReplanRequestMsg {
    /// Request counter of the executive, increasing from 1.
    pub request_id: u64,
    /// Time on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// [`ReplanReason`] as an integer; read with [`ReplanRequestMsg::reason`].
    pub reason: u32,
    /// The unload that failed (with `UnloadFailed`), else 0.
    pub failed_object: u32,
    /// Objects still to place (bit i = object i).
    pub remaining_mask: u64,
    /// Of those, the objects already on the tray.
    pub on_board_mask: u64,
    /// Where the base is, world frame: x, y (m), yaw (rad).
    pub pose: [f64; 3],
    /// Side of the failed unload (+1 near, -1 far, 0 none).
    pub failed_side: i32,
    /// [`REQUEST_AT_TABLE`] and zeros.
    pub flags: u32,
    /// Navigation goal of the failed unload, world x, y (m).
    pub failed_goal_m: [f64; 2],
    /// The tray as the executive believes it: per slot, the object in it plus one (0: empty).
    /// The plan's loads go into the slots free here.
    pub tray: [u8; MAX_TRAY_SLOTS],
}

/// Slots of the largest tray the messages describe.
pub const MAX_TRAY_SLOTS: usize = 8;

/// [`ReplanRequestMsg::flags`]: the base stands at a table (it just loaded or unloaded, or the
/// collision monitor held it in front of something): the plan's first leg backs out first.
pub const REQUEST_AT_TABLE: u32 = 1;

impl ReplanRequestMsg {
    /// The reason, checked.
    pub fn reason(&self) -> Result<ReplanReason, MessageError> {
        ReplanReason::from_wire(self.reason)
    }

    /// Sets the reason.
    pub fn set_reason(&mut self, reason: ReplanReason) {
        self.reason = reason as u32;
    }
}

// ---------------------------------------------------------------------------------------------
// load/request

/// The executive asks the people at the loading station to put objects on the tray
/// (`load/request`): what the robot's display shows them. One request per load step; the
/// station (a person, or the HIL world) loads exactly `object_mask`, once per `request_id`, in
/// object order into the free tray slots (the order the executive assumes).
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::LoadRequestMsg/v2")]
pub struct LoadRequestMsg {
    /// Load request counter of the executive, increasing from 1.
    pub request_id: u64,
    /// Time on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// The plan whose load step this is.
    pub plan_id: u64,
    /// The objects to put on the tray (bit i = object i): the load step's mask.
    pub object_mask: u64,
    /// The loading station the base stands at (the step's goal), world x, y (m).
    pub station_m: [f64; 2],
    /// Index of the load step in its plan.
    pub step_index: u32,
    /// Zero.
    pub reserved: u32,
    /// Where each object goes, as the plan says: per slot, the object to put in it plus one
    /// (0: none of this request's).
    pub slots: [u8; MAX_TRAY_SLOTS],
}

impl LoadRequestMsg {
    /// A request for `object_mask` at `station_m`.
    pub fn new(
        request_id: u64,
        stamp_ns: u64,
        plan_id: u64,
        step_index: u32,
        object_mask: u64,
        station_m: [f64; 2],
    ) -> Self {
        Self {
            request_id,
            stamp_ns,
            plan_id,
            object_mask,
            station_m,
            step_index,
            reserved: 0,
            slots: [0; MAX_TRAY_SLOTS],
        }
    }

    /// The station, checked: both coordinates finite.
    pub fn station(&self) -> Result<[f64; 2], MessageError> {
        match self.station_m.iter().position(|v| !v.is_finite()) {
            Some(i) => Err(MessageError::NotFinite {
                message: "LoadRequestMsg",
                field: "station_m",
                index: i as u32,
            }),
            None => Ok(self.station_m),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// heatmaps

/// Rows of a heatmap (the near crop's layout, docs/architecture.md).
pub const HEATMAP_ROWS: usize = 32;
/// Columns of a heatmap.
pub const HEATMAP_COLS: usize = 64;
/// Most (target, side) locations one heatmaps message carries: 12 objects on both sides.
pub const MAX_HEATMAPS: usize = 24;

/// Psi's heatmap of one (target, side) location.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::LocationHeatmap/v1")]
pub struct LocationHeatmap {
    /// The object whose target this is.
    pub object_index: u32,
    /// +1 near side, -1 far side.
    pub side: i32,
    /// Object goal on the table, world frame, metres.
    pub target_m: [f64; 3],
    /// Feasibility F of the location (eq. 4, closed form).
    pub feasibility: f64,
    /// Predicted success per cell, row-major, 0..=1.
    pub values: [f32; HEATMAP_ROWS * HEATMAP_COLS],
}

/// Psi's heatmaps of every location of a task (`heatmaps`), from one camera frame.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::HeatmapsMsg/v1")]
pub struct HeatmapsMsg {
    /// Time on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// The camera frame the heatmaps come from.
    pub source_frame_id: u64,
    /// Valid entries in `locations`; read with [`HeatmapsMsg::locations`].
    pub count: u32,
    /// Zero.
    pub reserved: u32,
    /// The heatmaps.
    pub locations: [LocationHeatmap; MAX_HEATMAPS],
}

impl HeatmapsMsg {
    /// The valid heatmaps, checked.
    pub fn locations(&self) -> Result<&[LocationHeatmap], MessageError> {
        self.locations
            .get(..self.count as usize)
            .ok_or(MessageError::CountTooLarge {
                message: "HeatmapsMsg",
                field: "count",
                count: u64::from(self.count),
                capacity: MAX_HEATMAPS as u64,
            })
    }
}

// ---------------------------------------------------------------------------------------------
// base/pose

/// Where a localisation fix comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum PoseFixKind {
    /// The localiser's pose in the map (e.g. laser scan matching).
    Global = 1,
    /// A table-edge detector's pose relative to the banquet table, turned into the world frame
    /// through the table's pose in the map; much more precise, valid only near the table.
    TableRelative = 2,
}

impl PoseFixKind {
    fn from_wire(value: u32) -> Result<Self, MessageError> {
        Ok(match value {
            1 => Self::Global,
            2 => Self::TableRelative,
            _ => {
                return Err(MessageError::UnknownEnumValue {
                    message: "BasePoseMsg",
                    field: "kind",
                    value,
                });
            }
        })
    }
}

/// A localisation fix of the base (`base/pose`).
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::BasePoseMsg/v1")]
pub struct BasePoseMsg {
    /// Fix counter of the publisher, increasing.
    pub seq: u64,
    /// Time the fix was measured, runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// [`PoseFixKind`] as an integer; read with [`BasePoseMsg::kind`].
    pub kind: u32,
    /// Zero.
    pub reserved: u32,
    /// World x, metres.
    pub x_m: f64,
    /// World y, metres.
    pub y_m: f64,
    /// Heading, radians.
    pub yaw_rad: f64,
    /// Standard deviation of x and y, metres.
    pub sigma_xy_m: f64,
    /// Standard deviation of the heading, radians.
    pub sigma_yaw_rad: f64,
}

impl BasePoseMsg {
    /// A fix of `kind`: pose (x, y, yaw) and its standard deviations.
    pub fn fix(
        seq: u64,
        stamp_ns: u64,
        kind: PoseFixKind,
        pose: [f64; 3],
        sigma_xy_m: f64,
        sigma_yaw_rad: f64,
    ) -> Self {
        Self {
            seq,
            stamp_ns,
            kind: kind as u32,
            reserved: 0,
            x_m: pose[0],
            y_m: pose[1],
            yaw_rad: pose[2],
            sigma_xy_m,
            sigma_yaw_rad,
        }
    }

    /// The kind, checked.
    pub fn kind(&self) -> Result<PoseFixKind, MessageError> {
        PoseFixKind::from_wire(self.kind)
    }

    /// Sets the kind.
    pub fn set_kind(&mut self, kind: PoseFixKind) {
        self.kind = kind as u32;
    }

    /// The pose, if every number is finite and the sigmas are not negative.
    pub fn pose(&self) -> Result<[f64; 3], MessageError> {
        let all = [
            self.x_m,
            self.y_m,
            self.yaw_rad,
            self.sigma_xy_m,
            self.sigma_yaw_rad,
        ];
        if all.iter().all(|v| v.is_finite()) && self.sigma_xy_m >= 0.0 && self.sigma_yaw_rad >= 0.0
        {
            Ok([self.x_m, self.y_m, self.yaw_rad])
        } else {
            Err(MessageError::NotFinite {
                message: "BasePoseMsg",
                field: "pose",
                index: 0,
            })
        }
    }
}

// ---------------------------------------------------------------------------------------------
// health

/// A process is alive (`health`), sent at a fixed rate; a reader that misses them for its
/// timeout treats the process as dead.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::HeartbeatMsg/v1")]
pub struct HeartbeatMsg {
    /// Counter, increasing.
    pub seq: u64,
    /// Time on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// [`ProcessRole`] as an integer; read with [`HeartbeatMsg::role`].
    pub role: u32,
    /// Operating-system process id.
    pub pid: u32,
    /// Loop overruns counted so far.
    pub overruns: u64,
}

impl HeartbeatMsg {
    /// The role, checked.
    pub fn role(&self) -> Result<ProcessRole, MessageError> {
        ProcessRole::from_wire(self.role)
    }

    /// Sets the role.
    pub fn set_role(&mut self, role: ProcessRole) {
        self.role = role as u32;
    }
}

/// The operator's enable (`operator/enable`): the one explicit command that arms the robot at
/// start and lets it go on after a latched safety stop whose cause has cleared. The executive
/// takes only an enable stamped after it started (or after the stop it releases), so a
/// restarted executive never re-arms on an old one.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::OperatorEnableMsg/v1")]
pub struct OperatorEnableMsg {
    /// Counter, increasing per operator.
    pub seq: u64,
    /// When the operator gave it, runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// Operating-system process id of the sender.
    pub pid: u32,
    /// Zero.
    pub reserved: u32,
}

/// Where the base really is (`world/truth`): published by the simulated world only, never
/// read by an onboard process (the executive knows its estimate, not this). The recorder logs
/// it, so that a HIL mission's log shows the estimate against the truth (`/world/truth`, and
/// the `truth_base_link` frame in `/tf`).
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::TruthMsg/v1")]
pub struct TruthMsg {
    /// Counter, increasing.
    pub seq: u64,
    /// Simulated time of the truth, runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// World x of the base's centre, metres.
    pub x_m: f64,
    /// World y, metres.
    pub y_m: f64,
    /// Heading, radians.
    pub yaw_rad: f64,
    /// Forward speed, m/s.
    pub speed_mps: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The layouts are the protocol between processes: a change must bump the `/vN` type names.
    #[test]
    fn wire_sizes_are_fixed() {
        assert_eq!(size_of::<TaskStep>(), 104);
        assert_eq!(size_of::<TaskPlanMsg>(), 80 + 104 * MAX_TASK_STEPS);
        assert_eq!(size_of::<ReplanRequestMsg>(), 96);
        assert_eq!(size_of::<LoadRequestMsg>(), 64);
        assert_eq!(size_of::<LocationHeatmap>(), 40 + 4 * 2048);
        assert_eq!(size_of::<BasePoseMsg>(), 64);
        assert_eq!(size_of::<HeartbeatMsg>(), 32);
        assert_eq!(size_of::<OperatorEnableMsg>(), 24);
        assert_eq!(size_of::<TruthMsg>(), 56);
    }

    #[test]
    fn accessors_reject_what_does_not_decode() {
        let mut step = TaskStep::navigate(1.0, 2.0, 0.5, 3.0);
        assert_eq!(step.kind(), Ok(TaskStepKind::Navigate));
        step.kind = 0;
        assert!(step.kind().is_err(), "a zeroed step has no kind");
        step.object_index = 64;
        assert!(step.object().is_err());
        let nan = TaskStep::navigate(f64::NAN, 0.0, 0.0, 0.0);
        assert!(!nan.is_finite());

        let mut fix = BasePoseMsg {
            seq: 1,
            stamp_ns: 0,
            kind: 2,
            reserved: 0,
            x_m: 1.0,
            y_m: 2.0,
            yaw_rad: 0.0,
            sigma_xy_m: 0.01,
            sigma_yaw_rad: 0.01,
        };
        assert_eq!(fix.kind(), Ok(PoseFixKind::TableRelative));
        assert_eq!(fix.pose(), Ok([1.0, 2.0, 0.0]));
        fix.sigma_xy_m = -1.0;
        assert!(fix.pose().is_err());
        fix.kind = 9;
        assert!(fix.kind().is_err());
    }

    #[test]
    fn a_load_request_carries_its_mask_and_checks_its_station() {
        let mut m = LoadRequestMsg::new(3, 10, 2, 4, 0b1010, [0.0, 1.05]);
        assert_eq!((m.request_id, m.object_mask, m.step_index), (3, 0b1010, 4));
        assert_eq!(m.station(), Ok([0.0, 1.05]));
        m.station_m[1] = f64::INFINITY;
        assert!(matches!(
            m.station(),
            Err(MessageError::NotFinite { index: 1, .. })
        ));
    }

    #[test]
    fn unload_steps_keep_their_side() {
        let step = TaskStep::unload(2, TableSide::Far, [1.0, 6.0, 1.3], [1.0, 6.8, -1.57], 0.7);
        assert_eq!(step.side(), Ok(TableSide::Far));
        assert_eq!(step.object(), Ok(2));
        assert_eq!(step.kind(), Ok(TaskStepKind::Unload));
    }
}
