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
}

/// Planar pose of the base in the world frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose2 {
    /// x, m.
    pub x_m: f32,
    /// y, m.
    pub y_m: f32,
    /// Heading, rad, counter-clockwise from +x.
    pub yaw_rad: f32,
}

impl Pose2 {
    /// A pose.
    pub const fn new(x_m: f32, y_m: f32, yaw_rad: f32) -> Self {
        Self { x_m, y_m, yaw_rad }
    }

    /// Unicycle motion for `dt_s` at constant `twist`, integrated exactly along the arc.
    pub fn integrate(&self, twist: Twist, dt_s: f32) -> Self {
        let dtheta = twist.yaw_rate_radps * dt_s;
        let ds = twist.speed_mps * dt_s;
        // Midpoint heading is exact for a circular arc once the chord length is used.
        let chord = if dtheta.abs() < 1e-6 {
            ds
        } else {
            2.0 * ds / dtheta * libm::sinf(dtheta / 2.0)
        };
        let mid = self.yaw_rad + dtheta / 2.0;
        Self {
            x_m: self.x_m + chord * libm::cosf(mid),
            y_m: self.y_m + chord * libm::sinf(mid),
            yaw_rad: wrap_angle(self.yaw_rad + dtheta),
        }
    }
}

/// Wraps an angle into (-pi, pi].
pub fn wrap_angle(rad: f32) -> f32 {
    let two_pi = 2.0 * core::f32::consts::PI;
    let mut a = libm::fmodf(rad + core::f32::consts::PI, two_pi);
    if a <= 0.0 {
        a += two_pi;
    }
    a - core::f32::consts::PI
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::PI;

    #[test]
    fn full_circle_returns_to_start() {
        let mut p = Pose2::default();
        // 1 rad/s at 1 m/s: radius 1, full circle in 2 pi s.
        let twist = Twist::new(1.0, 1.0);
        let steps = 629;
        for _ in 0..steps {
            p = p.integrate(twist, 2.0 * PI / steps as f32);
        }
        assert!(p.x_m.abs() < 1e-3 && p.y_m.abs() < 1e-3, "{p:?}");
        // Quarter circle: ends at (1, 1) heading +y.
        let q = Pose2::default().integrate(twist, PI / 2.0);
        assert!((q.x_m - 1.0).abs() < 1e-5 && (q.y_m - 1.0).abs() < 1e-5);
        assert!((q.yaw_rad - PI / 2.0).abs() < 1e-5);
    }

    #[test]
    fn wrap_angle_range() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-5);
        assert!((wrap_angle(-PI / 2.0) + PI / 2.0).abs() < 1e-6);
        assert!((wrap_angle(2.0 * PI + 0.1) - 0.1).abs() < 1e-5);
    }
}
