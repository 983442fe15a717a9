//! The runtime's iceoryx2 services, typed: camera frames, GROP plans, base and arm state,
//! events. Every message is a `#[repr(C)]` plain-data type that travels zero-copy through
//! shared memory; every service name starts with a namespace, so that a robot, a HIL run and
//! each test live side by side without seeing each other.
//!
//! | topic | message | history for late joiners |
//! |---|---|---|
//! | `<ns>/base/state` | [`BaseStateMsg`] | newest state |
//! | `<ns>/arm/state` | [`ArmStateMsg`] | newest state |
//! | `<ns>/events` | [`EventMsg`] | none |
//! | `<ns>/plan/task` | [`TaskPlanMsg`] (v2: load steps, 128 steps) | newest plan |
//! | `<ns>/plan/request` | [`ReplanRequestMsg`] | none |
//! | `<ns>/load/request` | [`LoadRequestMsg`] (the objects to put on the tray) | none |
//! | `<ns>/heatmaps` | [`HeatmapsMsg`] | newest |
//! | `<ns>/base/pose` | [`BasePoseMsg`] (localisation fixes) | newest fix |
//! | `<ns>/health` | [`HeartbeatMsg`] | none |
//! | `<ns>/camera/frame` | [`CameraFrameMsg`] (1280 x 960 RGB8 max + metric header) | newest frame |
//! | `<ns>/arm/io` | [`ArmIoMsg`] (every call on the arm and its answer) | none |
//! | `<ns>/operator/enable` | [`OperatorEnableMsg`] (the operator's enable) | newest |
//! | `<ns>/base/scan` | [`ScanMsg`] (a revolution of the range sensor) | newest |
//! | `<ns>/world/truth` | [`TruthMsg`] (the simulated world's truth; HIL only) | newest |
//!
//! ```no_run
//! use std::time::Duration;
//! use grop_ipc::{BaseStateMsg, IpcNode};
//!
//! let node = IpcNode::new("robot", "base-driver")?;
//! let publisher = node.publisher::<BaseStateMsg>()?;
//! publisher.publish_with(|state| {
//!     state.seq = 1;
//!     state.speed_mps = 0.4;
//! })?;
//!
//! let executive = IpcNode::new("robot", "executive")?;
//! let subscriber = executive.subscriber::<BaseStateMsg>()?;
//! if let Some(state) = subscriber.recv_timeout(Duration::from_millis(20))? {
//!     println!("base at {} m/s", state.speed_mps);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A subscriber wakes on its topic's event service (`<ns>/<topic>/wake`), so `recv_timeout`
//! sleeps instead of polling. Staleness is the reader's decision: every message carries
//! `stamp_ns` from the runtime clock, and [`Received::age_ns`] / [`Received::is_stale`] compare
//! it with the reader's now.

mod admit;
mod arm_io;
mod camera;
mod messages;
mod mission;
mod port;
mod scan;

pub use admit::{Admission, AdmittingSubscriber, Refusal, Sender, Sequenced};
pub use arm_io::{
    ARM_FLAG_CLOSE, ARM_FLAG_EMERGENCY_STOP, ARM_FLAG_PROGRAM_RUNNING, ARM_FLAG_PROTECTIVE_STOP,
    ARM_SAFETY_MODE_SHIFT, ARM_STATUS_DONE, ARM_STATUS_DONE_HOLDING, ARM_STATUS_RUNNING, ArmCall,
    ArmIoMsg, ArmOutcome,
};
pub use camera::{
    CAMERA_MAX_BYTES, CAMERA_MAX_HEIGHT_PX, CAMERA_MAX_WIDTH_PX, CameraFrameHeader, CameraFrameMsg,
    PixelFormat,
};
pub use messages::{
    ArmSafety, ArmStateMsg, BaseMode, BaseStateMsg, EVENT_DETAIL_CAPACITY, EventKind, EventMsg,
    MessageError, MonitorState, NO_CLEARANCE_CM, ProcessRole, TableSide,
};
pub use mission::{
    BasePoseMsg, HEATMAP_COLS, HEATMAP_ROWS, HeartbeatMsg, HeatmapsMsg, LoadRequestMsg,
    LocationHeatmap, MAX_HEATMAPS, MAX_TASK_OBJECTS, MAX_TASK_STEPS, MAX_TRAY_SLOTS,
    OperatorEnableMsg, PoseFixKind, REQUEST_AT_TABLE, ReplanReason, ReplanRequestMsg, TaskPlanMsg,
    TaskStep, TaskStepKind, TruthMsg,
};
pub use port::{
    FrameError, IpcNode, NodeError, PortError, PublishError, ReceiveError, Received,
    TopicPublisher, TopicSubscriber, wait_any,
};
pub use scan::{SCAN_BINS, ScanMsg};

/// A message type with its service: name and queue sizes. Implemented for the message types of
/// this crate only (sealed), each of which is plain data for which all-zero bytes are a valid
/// value; [`TopicPublisher::publish_with`] relies on that.
pub trait Topic:
    sealed::Sealed + iceoryx2::prelude::ZeroCopySend + core::fmt::Debug + 'static
{
    /// Service name below the namespace, e.g. `camera/frame`.
    const NAME: &'static str;
    /// How many of the newest messages a subscriber that joins late receives at once.
    const HISTORY: usize;
    /// Messages a subscriber buffers before the oldest are overwritten.
    const BUFFER: usize;
    /// Most subscribers (bounds the shared memory a publisher reserves).
    const MAX_SUBSCRIBERS: usize;
    /// Most publishers (several for events; one per device for states).
    const MAX_PUBLISHERS: usize;
    /// Timestamp of a message, runtime clock, nanoseconds.
    fn stamp_ns(&self) -> u64;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::BaseStateMsg {}
    impl Sealed for super::ArmStateMsg {}
    impl Sealed for super::EventMsg {}
    impl Sealed for super::TaskPlanMsg {}
    impl Sealed for super::ReplanRequestMsg {}
    impl Sealed for super::LoadRequestMsg {}
    impl Sealed for super::HeatmapsMsg {}
    impl Sealed for super::BasePoseMsg {}
    impl Sealed for super::HeartbeatMsg {}
    impl Sealed for super::CameraFrameMsg {}
    impl Sealed for super::ArmIoMsg {}
    impl Sealed for super::OperatorEnableMsg {}
    impl Sealed for super::ScanMsg {}
    impl Sealed for super::TruthMsg {}
}

impl Topic for BaseStateMsg {
    const NAME: &'static str = "base/state";
    const HISTORY: usize = 1;
    // 50 Hz for over a second, for a reader that logs every state.
    const BUFFER: usize = 64;
    const MAX_SUBSCRIBERS: usize = 8;
    const MAX_PUBLISHERS: usize = 2;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for ScanMsg {
    const NAME: &'static str = "base/scan";
    const HISTORY: usize = 1;
    // 10 revolutions a second; the recorder reads every cycle.
    const BUFFER: usize = 8;
    const MAX_SUBSCRIBERS: usize = 8;
    const MAX_PUBLISHERS: usize = 2;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for TruthMsg {
    const NAME: &'static str = "world/truth";
    const HISTORY: usize = 1;
    // 20 Hz; the recorder reads every cycle.
    const BUFFER: usize = 16;
    const MAX_SUBSCRIBERS: usize = 4;
    // The one simulated world.
    const MAX_PUBLISHERS: usize = 1;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for ArmStateMsg {
    const NAME: &'static str = "arm/state";
    const HISTORY: usize = 1;
    // RTDE runs at 500 Hz.
    const BUFFER: usize = 256;
    const MAX_SUBSCRIBERS: usize = 8;
    const MAX_PUBLISHERS: usize = 2;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for EventMsg {
    const NAME: &'static str = "events";
    // Events are things that happen now; a late joiner should not act on old ones.
    const HISTORY: usize = 0;
    const BUFFER: usize = 64;
    const MAX_SUBSCRIBERS: usize = 8;
    const MAX_PUBLISHERS: usize = 8;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for TaskPlanMsg {
    const NAME: &'static str = "plan/task";
    const HISTORY: usize = 1;
    const BUFFER: usize = 4;
    const MAX_SUBSCRIBERS: usize = 8;
    // One writer (docs/security.md): a second publisher cannot connect.
    const MAX_PUBLISHERS: usize = 1;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for ReplanRequestMsg {
    const NAME: &'static str = "plan/request";
    // A request is for the planner running now; a late joiner must not answer an old one.
    const HISTORY: usize = 0;
    const BUFFER: usize = 8;
    const MAX_SUBSCRIBERS: usize = 4;
    // One writer (docs/security.md): a second publisher cannot connect.
    const MAX_PUBLISHERS: usize = 1;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for LoadRequestMsg {
    const NAME: &'static str = "load/request";
    // A request is for the loading now; a station that joins late must not load an old one.
    const HISTORY: usize = 0;
    const BUFFER: usize = 8;
    const MAX_SUBSCRIBERS: usize = 4;
    // One writer (docs/security.md): a second publisher cannot connect.
    const MAX_PUBLISHERS: usize = 1;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for HeatmapsMsg {
    const NAME: &'static str = "heatmaps";
    const HISTORY: usize = 1;
    // About 200 KiB each; readers want the newest.
    const BUFFER: usize = 2;
    const MAX_SUBSCRIBERS: usize = 4;
    const MAX_PUBLISHERS: usize = 2;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for BasePoseMsg {
    const NAME: &'static str = "base/pose";
    const HISTORY: usize = 1;
    // 10 Hz fixes for over a second.
    const BUFFER: usize = 16;
    const MAX_SUBSCRIBERS: usize = 8;
    // One writer (docs/security.md): a second publisher cannot connect.
    const MAX_PUBLISHERS: usize = 1;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for HeartbeatMsg {
    const NAME: &'static str = "health";
    const HISTORY: usize = 0;
    const BUFFER: usize = 16;
    const MAX_SUBSCRIBERS: usize = 8;
    const MAX_PUBLISHERS: usize = 8;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for CameraFrameMsg {
    const NAME: &'static str = "camera/frame";
    const HISTORY: usize = 1;
    // Frames are 3.5 MiB and every subscriber slot is reserved in shared memory per publisher:
    // one buffered frame (the planner wants the newest), few readers; a second publisher slot
    // lets a restarted camera process join before the dead one is cleaned up.
    const BUFFER: usize = 1;
    const MAX_SUBSCRIBERS: usize = 3;
    const MAX_PUBLISHERS: usize = 2;
    fn stamp_ns(&self) -> u64 {
        self.header.stamp_ns
    }
}

impl Topic for OperatorEnableMsg {
    const NAME: &'static str = "operator/enable";
    // The newest, for an executive that starts after it: it takes it only if it was given
    // after its own start (a restart is not an enable).
    const HISTORY: usize = 1;
    const BUFFER: usize = 4;
    const MAX_SUBSCRIBERS: usize = 4;
    // The deployment's one operator (a console, `grop enable`, the HIL world).
    const MAX_PUBLISHERS: usize = 1;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl Topic for ArmIoMsg {
    const NAME: &'static str = "arm/io";
    const HISTORY: usize = 0;
    // Up to three calls a 2 ms cycle; a recorder drains every cycle.
    const BUFFER: usize = 256;
    const MAX_SUBSCRIBERS: usize = 4;
    const MAX_PUBLISHERS: usize = 2;
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}
