//! Speed and acceleration limits for a unicycle command, applied once per control period.

use crate::Twist;

/// Limits, all magnitudes (non-negative).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwistLimits {
    /// Highest forward speed, m/s.
    pub max_forward_mps: f32,
    /// Highest reverse speed, m/s.
    pub max_reverse_mps: f32,
    /// Highest yaw rate, rad/s.
    pub max_yaw_rate_radps: f32,
    /// Acceleration when speeding up, m/s^2.
    pub max_accel_mps2: f32,
    /// Deceleration when slowing down, m/s^2.
    pub max_decel_mps2: f32,
    /// Yaw acceleration, rad/s^2 (both ways).
    pub max_yaw_accel_radps2: f32,
}

impl Default for TwistLimits {
    /// The robot's defaults: 0.4 m/s cruise (DESIGN.md), gentle limits for a base carrying an
    /// arm and dishes.
    fn default() -> Self {
        Self {
            max_forward_mps: 0.5,
            max_reverse_mps: 0.2,
            max_yaw_rate_radps: 1.0,
            max_accel_mps2: 0.5,
            max_decel_mps2: 1.0,
            max_yaw_accel_radps2: 2.0,
        }
    }
}

/// Why limits were rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LimitsError {
    /// A limit is negative, NaN or infinite; names the field.
    Invalid(&'static str),
}

impl core::fmt::Display for LimitsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LimitsError::Invalid(field) => write!(f, "limit {field} must be finite and >= 0"),
        }
    }
}

impl core::error::Error for LimitsError {}

impl TwistLimits {
    /// Checks that every limit is finite and non-negative.
    pub fn validate(&self) -> Result<(), LimitsError> {
        let fields = [
            ("max_forward_mps", self.max_forward_mps),
            ("max_reverse_mps", self.max_reverse_mps),
            ("max_yaw_rate_radps", self.max_yaw_rate_radps),
            ("max_accel_mps2", self.max_accel_mps2),
            ("max_decel_mps2", self.max_decel_mps2),
            ("max_yaw_accel_radps2", self.max_yaw_accel_radps2),
        ];
        for (name, v) in fields {
            if !v.is_finite() || v < 0.0 {
                return Err(LimitsError::Invalid(name));
            }
        }
        Ok(())
    }

    /// Clamps a target into the speed envelope; a non-finite target becomes zero (stop).
    pub fn clamp(&self, target: Twist) -> Twist {
        if !target.is_finite() {
            return Twist::ZERO;
        }
        Twist {
            speed_mps: target
                .speed_mps
                .clamp(-self.max_reverse_mps, self.max_forward_mps),
            yaw_rate_radps: target
                .yaw_rate_radps
                .clamp(-self.max_yaw_rate_radps, self.max_yaw_rate_radps),
        }
    }
}

/// Moves `current` toward `target` by at most `accel * dt` when moving away from zero and
/// `decel * dt` when moving toward it (so a stop always uses the deceleration limit).
pub fn slew(current: f32, target: f32, accel: f32, decel: f32, dt_s: f32) -> f32 {
    let delta = target - current;
    if delta == 0.0 {
        return target;
    }
    let toward_zero = current != 0.0 && (current > 0.0) != (delta > 0.0);
    let max_step = if toward_zero { decel } else { accel } * dt_s;
    if delta.abs() <= max_step {
        return target;
    }
    let next = current + max_step.copysign(delta);
    // Crossing zero on the deceleration limit: stop at zero this period, accelerate the next.
    if toward_zero && (next > 0.0) != (current > 0.0) {
        return 0.0;
    }
    next
}

/// Applies [`TwistLimits`] period by period; remembers the last output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwistLimiter {
    limits: TwistLimits,
    output: Twist,
}

impl TwistLimiter {
    /// A limiter starting at rest.
    pub const fn new(limits: TwistLimits) -> Self {
        Self {
            limits,
            output: Twist::ZERO,
        }
    }

    /// The limits.
    pub const fn limits(&self) -> &TwistLimits {
        &self.limits
    }

    /// The last output.
    pub const fn output(&self) -> Twist {
        self.output
    }

    /// Forces the state (for example to the measured velocity after a mode change).
    pub fn reset_to(&mut self, twist: Twist) {
        self.output = if twist.is_finite() {
            twist
        } else {
            Twist::ZERO
        };
    }

    /// One period of `dt_s` toward `target` (clamped first); returns the new command.
    pub fn step(&mut self, target: Twist, dt_s: f32) -> Twist {
        let target = self.limits.clamp(target);
        let dt_s = if dt_s.is_finite() && dt_s > 0.0 {
            dt_s
        } else {
            0.0
        };
        let l = &self.limits;
        self.output = Twist {
            speed_mps: slew(
                self.output.speed_mps,
                target.speed_mps,
                l.max_accel_mps2,
                l.max_decel_mps2,
                dt_s,
            ),
            yaw_rate_radps: slew(
                self.output.yaw_rate_radps,
                target.yaw_rate_radps,
                l.max_yaw_accel_radps2,
                l.max_yaw_accel_radps2,
                dt_s,
            ),
        };
        self.output
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramps_up_at_accel_and_down_at_decel() {
        let mut l = TwistLimiter::new(TwistLimits::default());
        let mut steps = 0;
        while l.output().speed_mps < 0.5 {
            let out = l.step(Twist::new(2.0, 0.0), 0.02);
            assert!(out.speed_mps <= 0.5 + 1e-6);
            steps += 1;
        }
        // 0.5 m/s at 0.5 m/s^2 = 1 s = 50 periods of 20 ms (one more for f32 rounding).
        assert!((50..=51).contains(&steps), "{steps}");
        let mut steps = 0;
        while l.output().speed_mps > 0.0 {
            l.step(Twist::ZERO, 0.02);
            steps += 1;
        }
        // Stopping uses the 1 m/s^2 deceleration: 0.5 s.
        assert!((25..=26).contains(&steps), "{steps}");
    }

    #[test]
    fn reversing_stops_at_zero_first() {
        let mut l = TwistLimiter::new(TwistLimits::default());
        l.reset_to(Twist::new(0.01, 0.0));
        assert_eq!(l.step(Twist::new(-0.2, 0.0), 0.02).speed_mps, 0.0);
        assert!(l.step(Twist::new(-0.2, 0.0), 0.02).speed_mps < 0.0);
    }

    #[test]
    fn clamps_envelope_and_treats_nan_as_stop() {
        let limits = TwistLimits::default();
        assert_eq!(limits.clamp(Twist::new(-3.0, 9.0)), Twist::new(-0.2, 1.0));
        assert_eq!(limits.clamp(Twist::new(f32::NAN, 0.5)), Twist::ZERO);
        let mut l = TwistLimiter::new(limits);
        l.reset_to(Twist::new(0.4, 0.0));
        assert!(l.step(Twist::new(f32::INFINITY, 0.0), 0.02).speed_mps < 0.4);
        assert_eq!(
            TwistLimits {
                max_decel_mps2: -1.0,
                ..limits
            }
            .validate(),
            Err(LimitsError::Invalid("max_decel_mps2"))
        );
    }

    #[test]
    fn slew_is_symmetric_for_negative_speeds() {
        assert_eq!(slew(-0.5, 0.0, 0.5, 1.0, 0.1), -0.4);
        assert_eq!(slew(0.0, -1.0, 0.5, 1.0, 0.1), -0.05);
        assert_eq!(slew(0.3, 0.3, 0.5, 1.0, 0.1), 0.3);
    }
}
