//! Control laws for the mobile base: `#![no_std]`, no heap, f32 (single-precision FPU), time as
//! integer microseconds from a monotonic clock the caller owns (wall clock on the robot, a
//! simulated clock in HIL), so every law is deterministic and replayable.
//!
//! * [`limiter::TwistLimiter`]: speed, yaw-rate, acceleration and deceleration limits applied at
//!   a fixed command rate.
//! * [`watchdog::Watchdog`]: "is this input fresh?"; stale or never-seen inputs mean stop.
//! * [`mode::ModeSequencer`]: request a mode, resend until the device reports it, time out.
//! * [`follower::PathFollower`]: pure-pursuit path following for a unicycle base.
//! * [`collision::CollisionMonitor`]: the last law before the driver: stop, slowdown, approach
//!   and docking shapes on raw range points.
//!
//! ```
//! use motion_control::{Twist, limiter::{TwistLimiter, TwistLimits}, watchdog::Watchdog};
//!
//! let mut limiter = TwistLimiter::new(TwistLimits::default());
//! let mut input_watchdog = Watchdog::new(100_000); // 100 ms
//! input_watchdog.feed(0);
//! let target = Twist::new(0.4, 0.0);
//! // 20 ms later (50 Hz): the input is fresh, so the limiter ramps toward it.
//! let wanted = if input_watchdog.is_stale(20_000) { Twist::ZERO } else { target };
//! let command = limiter.step(wanted, 0.02);
//! assert!(command.speed_mps > 0.0 && command.speed_mps < 0.4);
//! // 200 ms later nobody fed the watchdog: command zero, ramped at the deceleration limit.
//! assert!(input_watchdog.is_stale(200_000));
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod collision;
pub mod follower;
pub mod limiter;
pub mod mode;
pub mod watchdog;

use planar::Pose2F32;

/// Body-frame velocity of a unicycle base: forward speed and yaw rate (counter-clockwise
/// positive, seen from above).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Twist {
    /// Forward speed, m/s.
    pub speed_mps: f32,
    /// Yaw rate, rad/s, counter-clockwise positive.
    pub yaw_rate_radps: f32,
}

impl Twist {
    /// Standing still.
    pub const ZERO: Self = Self {
        speed_mps: 0.0,
        yaw_rate_radps: 0.0,
    };

    /// A twist from speed and yaw rate.
    pub const fn new(speed_mps: f32, yaw_rate_radps: f32) -> Self {
        Self {
            speed_mps,
            yaw_rate_radps,
        }
    }

    /// True when both components are finite.
    pub fn is_finite(&self) -> bool {
        self.speed_mps.is_finite() && self.yaw_rate_radps.is_finite()
    }

    /// Where a base that holds this twist for `dt_s` ends up, in the frame it started in: the
    /// exact arc ([`Pose2F32::advance`]).
    pub fn motion_over(&self, dt_s: f32) -> Pose2F32 {
        Pose2F32::IDENTITY.advance(self.speed_mps * dt_s, self.yaw_rate_radps * dt_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::PI;

    #[test]
    fn full_circle_returns_to_start() {
        let mut p = Pose2F32::IDENTITY;
        // 1 rad/s at 1 m/s: radius 1, full circle in 2 pi s.
        let twist = Twist::new(1.0, 1.0);
        let steps = 629;
        for _ in 0..steps {
            let dt = 2.0 * PI / steps as f32;
            p = p.advance(twist.speed_mps * dt, twist.yaw_rate_radps * dt);
        }
        assert!(p.x_m.abs() < 1e-3 && p.y_m.abs() < 1e-3, "{p:?}");
        // Quarter circle: ends at (1, 1) heading +y.
        let q = twist.motion_over(PI / 2.0);
        assert!((q.x_m - 1.0).abs() < 1e-5 && (q.y_m - 1.0).abs() < 1e-5);
        assert!((q.yaw_rad - PI / 2.0).abs() < 1e-5);
    }
}
