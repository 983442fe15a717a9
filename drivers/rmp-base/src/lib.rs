//! Segway RMP v3 base driver: mode changes, velocity commands at a fixed rate under speed and
//! acceleration limits, feedback decoded into odometry and status, an input watchdog that ramps
//! to zero when the caller goes quiet, and typed errors when the base stops answering.
//!
//! The driver is a state machine driven by [`RmpBase::tick`], called once per command period
//! (50 Hz by default) with the time of a monotonic clock the caller owns (wall clock on the
//! robot, a simulated clock in HIL, see `grop_clock::WallClock`). It speaks to the base through an
//! [`RmpLink`]; [`CanLink`] puts it on any `can_bus::CanBus` (SocketCAN, the iceoryx2 virtual
//! bus, the in-memory bus).
//!
//! ```
//! use std::time::Duration;
//! use can_bus::MemoryBus;
//! use motion_control::Twist;
//! use rmp_base::{BaseMode, CanLink, RmpBase, RmpBaseConfig};
//!
//! let bus = MemoryBus::new();
//! let mut base = RmpBase::new(CanLink::new(bus.join()), RmpBaseConfig::default())?;
//! base.request_mode(BaseMode::Tractor, Duration::ZERO);
//! let mut now = Duration::ZERO;
//! for _ in 0..3 {
//!     base.set_velocity(Twist::new(0.3, 0.0), now); // from the planner / executive
//!     // Nobody answers on this bus: after the response timeout tick() reports
//!     // BaseError::Silent and keeps commanding zero.
//!     let _ = base.tick(now);
//!     now += base.config().command_period;
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod driver;
mod link;
mod odometry;

pub use driver::{
    ACCEL_HEADROOM, BASE_SETTINGS, BaseError, BaseMode, BaseStatus, ConfigError,
    DRIVER_FEEDBACK_ITEMS, DisarmCause, RmpBase, RmpBaseConfig, Tick, VerifiedLimits, echo_item,
    same_setting,
};
pub use link::{CanLink, LinkError, RmpLink, from_can, to_can};
pub use odometry::Odometry;
