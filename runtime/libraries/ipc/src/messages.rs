//! The message types of the runtime's services: `#[repr(C)]`, plain data, zero-copy.
//!
//! Shared memory is written by other processes, so nothing here is trusted: enums travel as
//! integers and counts/lengths are checked by the accessors, which return [`MessageError`].
//! All-zero bytes are a valid value of every type (`publish_with` starts every loan from zeros;
//! `publish_frame` zeroes the image bytes a camera frame's header describes).

use iceoryx2::prelude::ZeroCopySend;

/// Why a received message does not make sense.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum MessageError {
    /// An enum field holds a value no variant has.
    #[error("{message}.{field} holds {value}, which is not a known value")]
    UnknownEnumValue {
        /// Message type.
        message: &'static str,
        /// Field name.
        field: &'static str,
        /// The raw value.
        value: u32,
    },
    /// A count or length field exceeds the capacity of its array.
    #[error("{message}.{field} is {count}, above the capacity {capacity}")]
    CountTooLarge {
        /// Message type.
        message: &'static str,
        /// Field name.
        field: &'static str,
        /// The count found.
        count: u64,
        /// The array's capacity.
        capacity: u64,
    },
    /// An image's width or height is zero, or larger than the frame buffer holds.
    #[error(
        "camera frame of {width_px} x {height_px} px does not fit the {max_width_px} x {max_height_px} px buffer (or is empty)"
    )]
    BadImageSize {
        /// Width found.
        width_px: u32,
        /// Height found.
        height_px: u32,
        /// Largest width.
        max_width_px: u32,
        /// Largest height.
        max_height_px: u32,
    },
    /// The text of an event is not UTF-8.
    #[error("event detail text is not UTF-8")]
    DetailNotUtf8,
    /// A number that must be finite (a goal, a pose) is NaN or infinite.
    #[error("{message}.{field}[{index}] holds a number that is not finite")]
    NotFinite {
        /// Message type.
        message: &'static str,
        /// Field name.
        field: &'static str,
        /// Entry of the field.
        index: u32,
    },
}

// ---------------------------------------------------------------------------------------------
// table sides (plan/task, plan/request)

/// Which side of the banquet table the robot unloads from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableSide {
    /// y < 6 m, facing +y.
    Near,
    /// y > 6 m, facing -y.
    Far,
}

impl TableSide {
    pub(crate) fn to_wire(self) -> i32 {
        match self {
            Self::Near => 1,
            Self::Far => -1,
        }
    }

    pub(crate) fn from_wire(value: i32, message: &'static str) -> Result<Self, MessageError> {
        match value {
            1 => Ok(Self::Near),
            -1 => Ok(Self::Far),
            other => Err(MessageError::UnknownEnumValue {
                message,
                field: "side",
                value: other as u32,
            }),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// process roles (health, events)

/// Which onboard process a heartbeat (`health`) or an event comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum ProcessRole {
    /// Perception and planning node.
    Planner = 1,
    /// Executive (base and arm loops).
    Executive = 2,
    /// The HIL world (simulated devices and clock).
    World = 3,
}

impl ProcessRole {
    pub(crate) fn from_wire(value: u32) -> Result<Self, MessageError> {
        Ok(match value {
            1 => Self::Planner,
            2 => Self::Executive,
            3 => Self::World,
            _ => {
                return Err(MessageError::UnknownEnumValue {
                    message: "HeartbeatMsg",
                    field: "role",
                    value,
                });
            }
        })
    }
}

// ---------------------------------------------------------------------------------------------
// base/state

/// Operational mode of the RMP base as the driver last saw it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum BaseMode {
    /// No feedback yet, or the link is lost.
    Unknown = 0,
    /// Drives disabled.
    Disabled = 1,
    /// Powered, not accepting motion.
    Standby = 2,
    /// Accepting motion commands.
    Tractor = 3,
    /// Decelerating to zero (loss of commands or a stop request).
    DecelToZero = 4,
    /// Powering down.
    PowerDown = 5,
    /// A fault latched; see `fault_bits`.
    Faulted = 6,
}

impl BaseMode {
    fn from_wire(value: u32) -> Result<Self, MessageError> {
        Ok(match value {
            0 => Self::Unknown,
            1 => Self::Disabled,
            2 => Self::Standby,
            3 => Self::Tractor,
            4 => Self::DecelToZero,
            5 => Self::PowerDown,
            6 => Self::Faulted,
            _ => {
                return Err(MessageError::UnknownEnumValue {
                    message: "BaseStateMsg",
                    field: "mode",
                    value,
                });
            }
        })
    }
}

/// What the collision monitor did with the last base cycle's command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum MonitorState {
    /// No range sensor: the command passes unchecked.
    Off = 0,
    /// Nothing in any zone.
    Clear = 1,
    /// Capped at docking speed (docking, or escaping the stop zone).
    Crawl = 2,
    /// Something in the slowdown zone: the command scaled down.
    Slowdown = 3,
    /// The projected footprint meets the stop zone soon: the command scaled down.
    Approach = 4,
    /// Something in the stop zone: zero.
    Stop = 5,
    /// No scan, or a stale one: zero.
    Stale = 6,
}

impl MonitorState {
    fn from_wire(value: u8) -> Result<Self, MessageError> {
        Ok(match value {
            0 => Self::Off,
            1 => Self::Clear,
            2 => Self::Crawl,
            3 => Self::Slowdown,
            4 => Self::Approach,
            5 => Self::Stop,
            6 => Self::Stale,
            _ => {
                return Err(MessageError::UnknownEnumValue {
                    message: "BaseStateMsg",
                    field: "monitor",
                    value: u32::from(value),
                });
            }
        })
    }
}

/// `BaseStateMsg::monitor_clearance_cm` when the monitor saw no point (or runs without a
/// sensor).
pub const NO_CLEARANCE_CM: u16 = u16::MAX;

/// Odometry and status of the mobile base (`base/state`), published by the base driver.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::BaseStateMsg/v2")]
pub struct BaseStateMsg {
    /// Message counter, increasing.
    pub seq: u64,
    /// Time of the feedback on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// Odometry pose, world x, metres.
    pub x_m: f64,
    /// Odometry pose, world y, metres.
    pub y_m: f64,
    /// Heading, radians.
    pub yaw_rad: f64,
    /// Forward speed, m/s.
    pub speed_mps: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: f64,
    /// Speed currently commanded by the driver (after its limits), m/s.
    pub commanded_speed_mps: f64,
    /// Yaw rate currently commanded, rad/s.
    pub commanded_yaw_rate_radps: f64,
    /// [`BaseMode`] as an integer; read with [`BaseStateMsg::mode`].
    pub mode: u32,
    /// Fault status bits as the base reports them (0: none).
    pub fault_bits: u32,
    /// 1 while the base answers, 0 after the driver lost it.
    pub link_up: u8,
    /// 1 while the driver's watchdog holds the base at zero velocity.
    pub watchdog_stopped: u8,
    /// [`MonitorState`] as an integer; read with [`BaseStateMsg::monitor`].
    pub monitor: u8,
    /// Zero.
    pub reserved0: u8,
    /// The collision monitor's clearance of the footprint to the nearest point, cm (saturated;
    /// [`NO_CLEARANCE_CM`]: none seen; 0: a point in the footprint).
    pub monitor_clearance_cm: u16,
    /// Zero.
    pub reserved: [u8; 2],
}

impl BaseStateMsg {
    /// The collision monitor's state, checked.
    pub fn monitor(&self) -> Result<MonitorState, MessageError> {
        MonitorState::from_wire(self.monitor)
    }

    /// Sets the collision monitor's state.
    pub fn set_monitor(&mut self, state: MonitorState) {
        self.monitor = state as u8;
    }

    /// The mode, checked.
    pub fn mode(&self) -> Result<BaseMode, MessageError> {
        BaseMode::from_wire(self.mode)
    }

    /// Sets the mode.
    pub fn set_mode(&mut self, mode: BaseMode) {
        self.mode = mode as u32;
    }
}

// ---------------------------------------------------------------------------------------------
// arm/state

/// Safety state of the UR5e as its controller reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum ArmSafety {
    /// No data yet, or the connection is lost.
    Unknown = 0,
    /// Normal operation.
    Normal = 1,
    /// Reduced mode.
    Reduced = 2,
    /// Protective stop.
    ProtectiveStop = 3,
    /// Emergency stop (robot or system).
    EmergencyStop = 4,
    /// Safeguard stop.
    SafeguardStop = 5,
    /// Fault or violation.
    Fault = 6,
}

impl ArmSafety {
    fn from_wire(value: u32) -> Result<Self, MessageError> {
        Ok(match value {
            0 => Self::Unknown,
            1 => Self::Normal,
            2 => Self::Reduced,
            3 => Self::ProtectiveStop,
            4 => Self::EmergencyStop,
            5 => Self::SafeguardStop,
            6 => Self::Fault,
            _ => {
                return Err(MessageError::UnknownEnumValue {
                    message: "ArmStateMsg",
                    field: "safety",
                    value,
                });
            }
        })
    }
}

/// Joint state, tool pose and gripper of the UR5e (`arm/state`), published by the arm driver.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::ArmStateMsg/v1")]
pub struct ArmStateMsg {
    /// Message counter, increasing.
    pub seq: u64,
    /// Time of the RTDE package on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// Actual joint positions, radians (base, shoulder, elbow, wrist 1-3).
    pub joints_rad: [f64; 6],
    /// Actual joint speeds, rad/s.
    pub joint_speeds_radps: [f64; 6],
    /// Tool flange pose in the arm base frame: x, y, z (m), rotation vector (rad).
    pub flange_pose: [f64; 6],
    /// Gripper opening, metres (0 closed).
    pub gripper_opening_m: f64,
    /// [`ArmSafety`] as an integer; read with [`ArmStateMsg::safety`].
    pub safety: u32,
    /// Robot mode as the controller reports it (RTDE `robot_mode`).
    pub robot_mode: i32,
    /// 1 while a program runs on the controller.
    pub program_running: u8,
    /// 1 while the driver is connected to the controller.
    pub connected: u8,
    /// 1 while the gripper reports an object held.
    pub object_held: u8,
    /// Zero.
    pub reserved: [u8; 5],
}

impl ArmStateMsg {
    /// The safety state, checked.
    pub fn safety(&self) -> Result<ArmSafety, MessageError> {
        ArmSafety::from_wire(self.safety)
    }

    /// Sets the safety state.
    pub fn set_safety(&mut self, safety: ArmSafety) {
        self.safety = safety as u32;
    }
}

// ---------------------------------------------------------------------------------------------
// events

/// Capacity of an event's text.
pub const EVENT_DETAIL_CAPACITY: usize = 112;

/// What happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
#[non_exhaustive]
pub enum EventKind {
    /// A new plan starts executing.
    PlanStarted = 1,
    /// The base reached a step's navigation goal.
    GoalReached = 2,
    /// An object was unloaded.
    UnloadSucceeded = 3,
    /// An unload failed (unreachable, collision, gripper); a replan follows.
    UnloadFailed = 4,
    /// The scene changed or a step failed: the planner is asked for a new plan.
    ReplanRequested = 5,
    /// Every step of the plan is done.
    PlanFinished = 6,
    /// An input went stale (commands, state, plan): motion stopped.
    StaleInput = 7,
    /// A device stopped answering (base on CAN, arm on TCP): motion stopped.
    LinkLost = 8,
    /// The base reported a fault.
    BaseFault = 9,
    /// The arm reported a protective or emergency stop.
    ArmStopped = 10,
    /// Objects were loaded onto the tray at the station.
    Loaded = 11,
    /// Another onboard process stopped (heartbeat lost): motion stopped.
    PeerLost = 12,
    /// The mission ended before its plan did (a lost device, a dead peer, an unrecoverable
    /// stop); the detail says why.
    MissionAborted = 13,
    /// The simulated world saw the base or the arm touch furniture (HIL only).
    Collision = 14,
    /// The simulated world judged a released object against its target (HIL only).
    ObjectJudged = 15,
    /// A leg of the plan was driven (or given up).
    LegFinished = 16,
    /// What the robot holds is not what the executive believes (a sensor of the robot file
    /// said so: the gripper closed on nothing where the tray should hold an object); the object
    /// is not placed, and the detail says which slot and object.
    TrayMismatch = 17,
    /// The planner cannot plan an object (its views, its goals); the detail says why. The rest
    /// is planned without it.
    NotPlanned = 18,
    /// The executive asked the loading station for objects (`load/request`).
    LoadRequested = 19,
    /// The collision monitor stopped the base (an obstacle in the stop zone, a stale scan) or
    /// let it go again, or the base stalled against something (commanded motion, none
    /// measured); the detail says which.
    Obstacle = 20,
    /// The operator's enable: waited for at start, taken (arming the base, or releasing a
    /// latched safety stop whose cause cleared), or refused (the cause is still there).
    Enable = 21,
    /// A command input (plan, fix, the planner's heartbeat) came from a publisher other than the
    /// deployment's, or out of sequence, and was refused (docs/security.md); the detail says
    /// which input, who sent it and how many were refused since the last report.
    InputRefused = 22,
}

impl EventKind {
    fn from_wire(value: u32) -> Result<Self, MessageError> {
        Ok(match value {
            1 => Self::PlanStarted,
            2 => Self::GoalReached,
            3 => Self::UnloadSucceeded,
            4 => Self::UnloadFailed,
            5 => Self::ReplanRequested,
            6 => Self::PlanFinished,
            7 => Self::StaleInput,
            8 => Self::LinkLost,
            9 => Self::BaseFault,
            10 => Self::ArmStopped,
            11 => Self::Loaded,
            12 => Self::PeerLost,
            13 => Self::MissionAborted,
            14 => Self::Collision,
            15 => Self::ObjectJudged,
            16 => Self::LegFinished,
            17 => Self::TrayMismatch,
            18 => Self::NotPlanned,
            19 => Self::LoadRequested,
            20 => Self::Obstacle,
            21 => Self::Enable,
            22 => Self::InputRefused,
            _ => {
                return Err(MessageError::UnknownEnumValue {
                    message: "EventMsg",
                    field: "kind",
                    value,
                });
            }
        })
    }
}

/// Something the executive or a driver wants the rest of the system to know (`events`).
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::EventMsg/v1")]
pub struct EventMsg {
    /// Message counter of the publisher, increasing.
    pub seq: u64,
    /// Time on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// The plan it concerns (0: none).
    pub plan_id: u64,
    /// [`EventKind`] as an integer; read with [`EventMsg::kind`].
    pub kind: u32,
    /// The plan step it concerns.
    pub step_index: u32,
    /// Bytes of `detail` in use.
    pub detail_len: u32,
    /// The publisher's [`ProcessRole`] as an integer, 0 when not said (this field was
    /// reserved, always zero, before: the layout is unchanged).
    pub source: u32,
    /// UTF-8 text for humans and logs; read with [`EventMsg::detail`].
    pub detail: [u8; EVENT_DETAIL_CAPACITY],
}

impl EventMsg {
    /// An event of `kind` with `detail` cut (at a character boundary) to the capacity.
    pub fn new(kind: EventKind, stamp_ns: u64, detail: &str) -> Self {
        let mut event = Self {
            seq: 0,
            stamp_ns,
            plan_id: 0,
            kind: kind as u32,
            step_index: 0,
            detail_len: 0,
            source: 0,
            detail: [0; EVENT_DETAIL_CAPACITY],
        };
        let mut end = detail.len().min(EVENT_DETAIL_CAPACITY);
        while !detail.is_char_boundary(end) {
            end -= 1;
        }
        event.detail[..end].copy_from_slice(&detail.as_bytes()[..end]);
        // Cannot truncate: at most EVENT_DETAIL_CAPACITY.
        event.detail_len = end as u32;
        event
    }

    /// The kind, checked.
    pub fn kind(&self) -> Result<EventKind, MessageError> {
        EventKind::from_wire(self.kind)
    }

    /// Says who publishes it.
    pub fn with_source(mut self, role: ProcessRole) -> Self {
        self.source = role as u32;
        self
    }

    /// Who published it (`None` when not said or unknown).
    pub fn source(&self) -> Option<ProcessRole> {
        ProcessRole::from_wire(self.source).ok()
    }

    /// The text, checked.
    pub fn detail(&self) -> Result<&str, MessageError> {
        let bytes =
            self.detail
                .get(..self.detail_len as usize)
                .ok_or(MessageError::CountTooLarge {
                    message: "EventMsg",
                    field: "detail_len",
                    count: u64::from(self.detail_len),
                    capacity: EVENT_DETAIL_CAPACITY as u64,
                })?;
        core::str::from_utf8(bytes).map_err(|_| MessageError::DetailNotUtf8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The layouts are the protocol between processes: a change must bump the `/vN` type names.
    #[test]
    fn wire_sizes_are_fixed() {
        assert_eq!(size_of::<BaseStateMsg>(), 88);
        assert_eq!(size_of::<ArmStateMsg>(), 184);
        assert_eq!(size_of::<EventMsg>(), 152);
    }

    #[test]
    fn zeroed_messages_decode_to_defined_values() {
        let base = BaseStateMsg {
            seq: 0,
            stamp_ns: 0,
            x_m: 0.0,
            y_m: 0.0,
            yaw_rad: 0.0,
            speed_mps: 0.0,
            yaw_rate_radps: 0.0,
            commanded_speed_mps: 0.0,
            commanded_yaw_rate_radps: 0.0,
            mode: 0,
            fault_bits: 0,
            link_up: 0,
            watchdog_stopped: 0,
            monitor: 0,
            reserved0: 0,
            monitor_clearance_cm: 0,
            reserved: [0; 2],
        };
        // A zeroed (never written) state says "unknown", never "tractor".
        assert_eq!(base.mode(), Ok(BaseMode::Unknown));
        assert_eq!(base.monitor(), Ok(MonitorState::Off));
        let mut stopped = base;
        stopped.set_monitor(MonitorState::Stop);
        assert_eq!(stopped.monitor(), Ok(MonitorState::Stop));
        stopped.monitor = 7;
        assert!(stopped.monitor().is_err());
        let mut event = EventMsg::new(EventKind::PlanStarted, 0, "");
        event.kind = 0;
        assert!(event.kind().is_err(), "a zeroed event has no kind");
        assert_eq!(event.detail(), Ok(""));
    }
}
