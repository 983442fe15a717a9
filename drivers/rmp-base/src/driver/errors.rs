//! What the driver reports: its errors and why it disarmed itself.

use std::time::Duration;

use rmp_codec::faults::FaultStatus;
use rmp_codec::feedback::FeedbackError;
use rmp_codec::v3::{NvmFloat, OperationalState};

use crate::link::LinkError;

use super::BaseMode;

/// Why a tick reports trouble. The driver has still done its safe action for the tick
/// (commanded zero where the variant says so); the condition is re-reported every tick while
/// it lasts.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BaseError {
    /// No feedback at all from the base for longer than the response timeout. Motion commands
    /// are zero until it answers again.
    #[error(
        "RMP base not answering: no feedback for {silent_for:?} (timeout {timeout:?}); commanding zero velocity"
    )]
    Silent {
        /// Time since the last complete feedback set (or since start).
        silent_for: Duration,
        /// The response timeout.
        timeout: Duration,
    },
    /// Frames arrive but no complete feedback set could be read for longer than the response
    /// timeout (feedback layout changed behind the driver's back, corrupted frames). Motion
    /// commands are zero.
    #[error(
        "RMP base feedback unreadable for {silent_for:?} (last error: {last_error:?}, expected {expected_frames} frames per set); commanding zero velocity"
    )]
    FeedbackUnreadable {
        /// Time since the last complete set.
        silent_for: Duration,
        /// The last assembly error, if any (partial sets alone leave none).
        last_error: Option<FeedbackError>,
        /// Frames per set in the layout the driver expects.
        expected_frames: usize,
    },
    /// At start-up the base did not take the feedback bitmaps: the forced configuration
    /// feedback echoed other bitmaps. The driver starts over (rewrites them).
    #[error(
        "RMP base kept feedback bitmaps {echoed:08x?} after {attempts} writes of {wanted:08x?}"
    )]
    FeedbackConfigRejected {
        /// Bitmaps written.
        wanted: [u32; 4],
        /// Bitmaps the base reports.
        echoed: [u32; 4],
        /// Write-and-verify rounds done.
        attempts: u8,
    },
    /// The base did not report the requested mode in time.
    #[error("RMP base did not enter {wanted:?} within {timeout:?} (it reports {reported:?})")]
    ModeTimeout {
        /// The mode asked for.
        wanted: BaseMode,
        /// The last reported operational state.
        reported: Option<OperationalState>,
        /// The mode timeout.
        timeout: Duration,
    },
    /// The base reports faults that stop motion.
    #[error("RMP base faulted ({}): motion is stopped", describe(.faults))]
    Faulted {
        /// Fault status words 1..4.
        faults: FaultStatus,
    },
    /// The base moved faster than commanded (beyond the configured tolerance): the driver
    /// commands zero and stays disarmed until [`crate::RmpBase::rearm`]. Re-reported every tick
    /// until then.
    #[error(
        "RMP base faster than commanded: {measured_mps} m/s (allowed {allowed_mps}), {measured_yaw_radps} rad/s (allowed {allowed_yaw_radps}); stopped until re-armed"
    )]
    Overspeed {
        /// Measured speed, m/s.
        measured_mps: f32,
        /// Commanded envelope plus tolerance, m/s.
        allowed_mps: f32,
        /// Measured yaw rate, rad/s.
        measured_yaw_radps: f32,
        /// Commanded yaw envelope plus tolerance, rad/s.
        allowed_yaw_radps: f32,
    },
    /// Another host sends motion (0x500) or configuration (0x501) commands on the bus: the
    /// base obeys whichever command came last, so nobody is in control. The driver commands
    /// zero and stays disarmed until [`crate::RmpBase::rearm`]; re-reported every tick until then.
    /// (A host never receives its own frames: SocketCAN does not loop them back to the
    /// sending socket, nor does the virtual bus.)
    #[error(
        "a second commander on the RMP bus: {frames} command frames not sent by this driver (last id {last_id:#05x}); stopped until re-armed"
    )]
    SecondCommander {
        /// Foreign command frames seen since start.
        frames: u64,
        /// Id of the last one.
        last_id: u16,
    },
    /// At start-up the base did not keep a limit the driver wrote into its stored settings
    /// (after the write-and-verify rounds): the driver stays disarmed, commanding zero, and
    /// reports this every tick. Nothing clears it but a new driver on a base that keeps the
    /// value.
    #[error(
        "RMP base did not take its {setting:?} setting: wrote {written}, read back {}; refusing to drive",
        read_back(.read)
    )]
    LimitNotTaken {
        /// The stored setting.
        setting: NvmFloat,
        /// The value written (from the robot file's limits).
        written: f32,
        /// The value the base reports (`None`: it reports none).
        read: Option<f32>,
    },
    /// After the limits were verified the base reported a different speed or yaw-rate limit:
    /// its normalised commands would now mean other speeds. The driver commands zero and stays
    /// disarmed until [`crate::RmpBase::rearm`] (and disarms again while the report differs).
    #[error(
        "RMP base reports its {setting:?} as {reported}, verified at start-up as {verified}; stopped until re-armed"
    )]
    LimitChanged {
        /// The stored setting.
        setting: NvmFloat,
        /// The value verified at start-up.
        verified: f32,
        /// The value reported now.
        reported: f32,
    },
    /// The link refused a frame.
    #[error("RMP link: {0}")]
    Link(#[from] LinkError),
}

fn read_back(read: &Option<f32>) -> String {
    match read {
        Some(v) => v.to_string(),
        None => "nothing (not in the feedback)".to_owned(),
    }
}

/// Why the driver disarmed itself. Disarmed, it commands zero velocity whatever the input,
/// until [`crate::RmpBase::rearm`] is called, even after the cause has cleared.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum DisarmCause {
    /// The base stopped answering (or its feedback became unreadable) after it had answered.
    LinkLost,
    /// The base reported a fault that stops motion.
    Faulted {
        /// Fault status words 1..4 when it was seen.
        faults: FaultStatus,
    },
    /// The base moved faster than commanded ([`crate::BaseError::Overspeed`]).
    Overspeed {
        /// Measured speed, m/s.
        measured_mps: f32,
        /// Commanded envelope plus tolerance, m/s.
        allowed_mps: f32,
        /// Measured yaw rate, rad/s.
        measured_yaw_radps: f32,
        /// Commanded yaw envelope plus tolerance, rad/s.
        allowed_yaw_radps: f32,
    },
    /// Another host sends motion or configuration commands on the bus
    /// ([`crate::BaseError::SecondCommander`]).
    SecondCommander,
    /// The base did not keep a limit written at start-up ([`crate::BaseError::LimitNotTaken`]).
    LimitNotTaken {
        /// The stored setting.
        setting: NvmFloat,
        /// The value written.
        written: f32,
        /// The value read back, if any.
        read: Option<f32>,
    },
    /// The base reported a limit other than the one verified ([`crate::BaseError::LimitChanged`]).
    LimitChanged {
        /// The stored setting.
        setting: NvmFloat,
        /// The verified value.
        verified: f32,
        /// The value reported.
        reported: f32,
    },
}

pub(super) fn describe(faults: &FaultStatus) -> String {
    let names: Vec<&str> = faults.active().map(|b| b.name).collect();
    if names.is_empty() {
        format!("fault words {:08x?}", faults.words())
    } else {
        names.join(", ")
    }
}
