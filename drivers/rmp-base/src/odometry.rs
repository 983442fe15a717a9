//! Dead reckoning from RMP feedback: travelled distance from the linear-position integrator,
//! heading from the difference of the wheel-position integrators over the track width.
//! Integrators are differenced between sets, so a reset integrator (or the first set) causes
//! no jump.

use std::time::Duration;

use planar::{Pose2, wrap_angle};

/// Pose and velocity of the base in its odometry frame (origin and heading where the driver
/// started, x forward, counter-clockwise yaw).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Odometry {
    /// x, m.
    pub x_m: f64,
    /// y, m.
    pub y_m: f64,
    /// Heading, rad, in (-pi, pi].
    pub yaw_rad: f64,
    /// Forward speed reported by the base, m/s.
    pub speed_mps: f64,
    /// Yaw rate reported by the base, rad/s, counter-clockwise positive.
    pub yaw_rate_radps: f64,
    /// Clock time of the feedback set this comes from.
    pub stamp: Duration,
}

impl Odometry {
    /// Where the base is, without the velocities.
    pub fn pose(&self) -> Pose2 {
        Pose2::new(self.x_m, self.y_m, self.yaw_rad)
    }
}

/// Integrator readings of one feedback set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Integrators {
    /// Linear position, m.
    pub linear_m: f64,
    /// Right-side wheel position (mean of front and rear), m.
    pub right_m: f64,
    /// Left-side wheel position, m.
    pub left_m: f64,
}

/// Largest believable change between two feedback sets; more means an integrator reset or a
/// bad word, and the step is skipped instead of teleporting the pose.
const MAX_STEP_M: f64 = 1.0;

#[derive(Debug, Clone, Default)]
pub(crate) struct DeadReckoning {
    pub odometry: Odometry,
    last: Option<Integrators>,
    pub skipped_steps: u64,
}

impl DeadReckoning {
    /// Forgets the last reading (after an integrator reset or a link loss).
    pub fn rebase(&mut self) {
        self.last = None;
    }

    /// Integrates the current reported velocities over `dt_s` (when the feedback carries no
    /// integrators).
    pub fn integrate_velocity(&mut self, dt_s: f64) {
        let o = &mut self.odometry;
        let dyaw = o.yaw_rate_radps * dt_s;
        let mid = o.yaw_rad + dyaw / 2.0;
        o.x_m += o.speed_mps * dt_s * mid.cos();
        o.y_m += o.speed_mps * dt_s * mid.sin();
        o.yaw_rad = wrap_angle(o.yaw_rad + dyaw);
    }

    /// Integrates one feedback set. Wheel positions are physical (the right side advancing
    /// more is a counter-clockwise turn whatever the protocol's yaw sign), so no sign applies.
    pub fn update(&mut self, now: Integrators, track_width_m: f64) {
        if let Some(prev) = self.last {
            let ds = now.linear_m - prev.linear_m;
            let d_right = now.right_m - prev.right_m;
            let d_left = now.left_m - prev.left_m;
            let dyaw = (d_right - d_left) / track_width_m;
            let finite = ds.is_finite() && dyaw.is_finite();
            if finite && ds.abs() <= MAX_STEP_M && (d_right - d_left).abs() <= 2.0 * MAX_STEP_M {
                let o = &mut self.odometry;
                let mid = o.yaw_rad + dyaw / 2.0;
                o.x_m += ds * mid.cos();
                o.y_m += ds * mid.sin();
                o.yaw_rad = wrap_angle(o.yaw_rad + dyaw);
            } else {
                self.skipped_steps += 1;
            }
        }
        self.last = Some(now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_then_turn_in_place() {
        let mut d = DeadReckoning::default();
        let track = 0.7;
        d.update(
            Integrators {
                linear_m: 5.0,
                right_m: 5.0,
                left_m: 5.0,
            },
            track,
        );
        assert_eq!(d.odometry.x_m, 0.0, "first set only sets the reference");
        d.update(
            Integrators {
                linear_m: 6.0,
                right_m: 6.0,
                left_m: 6.0,
            },
            track,
        );
        assert!((d.odometry.x_m - 1.0).abs() < 1e-12);
        // Quarter turn in place: the wheels move +-(pi/2)(track/2).
        let q = std::f64::consts::FRAC_PI_2 * track / 2.0;
        d.update(
            Integrators {
                linear_m: 6.0,
                right_m: 6.0 + q,
                left_m: 6.0 - q,
            },
            track,
        );
        assert!((d.odometry.yaw_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        d.update(
            Integrators {
                linear_m: 6.5,
                right_m: 6.5 + q,
                left_m: 6.5 - q,
            },
            track,
        );
        assert!((d.odometry.y_m - 0.5).abs() < 1e-12 && (d.odometry.x_m - 1.0).abs() < 1e-12);
        // An integrator reset (jump back to 0) is skipped, not integrated.
        d.update(
            Integrators {
                linear_m: 0.0,
                right_m: 0.0,
                left_m: 0.0,
            },
            track,
        );
        assert_eq!(d.skipped_steps, 1);
        assert!((d.odometry.y_m - 0.5).abs() < 1e-12);
    }
}
