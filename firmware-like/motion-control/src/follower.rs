//! Pure-pursuit path following for a unicycle base (Coulter 1992): steer toward a look-ahead
//! point on the path with curvature 2 y / L^2, rotate in place when the path lies behind, and
//! slow down so that the base can stop at the last point with the deceleration limit.

use heapless::Vec;
use planar::{Pose2F32, wrap_angle_f32};

use crate::Twist;

/// At the end of a docking line ([`PathFollower::set_line`]), a goal that lies more to the side
/// than ahead within this fraction of the look-ahead distance counts as reached.
const ARRIVE_BESIDE_FACTOR: f32 = 0.5;

/// Follower tuning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowerConfig {
    /// Look-ahead distance L, m.
    pub lookahead_m: f32,
    /// Cruise speed, m/s (the robot's 0.4 m/s by default).
    pub cruise_speed_mps: f32,
    /// Yaw-rate limit, rad/s.
    pub max_yaw_rate_radps: f32,
    /// Deceleration used to plan the stop at the end, m/s^2.
    pub stop_decel_mps2: f32,
    /// Distance to the last point at which the path counts as done, m.
    pub goal_tolerance_m: f32,
    /// Heading error above which the base turns in place first, rad.
    pub turn_in_place_above_rad: f32,
}

impl Default for FollowerConfig {
    fn default() -> Self {
        Self {
            lookahead_m: 0.3,
            cruise_speed_mps: 0.4,
            max_yaw_rate_radps: 1.0,
            stop_decel_mps2: 0.5,
            goal_tolerance_m: 0.05,
            turn_in_place_above_rad: 1.0,
        }
    }
}

/// Why a path was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathError {
    /// No points.
    Empty,
    /// More points than the follower's capacity.
    TooLong {
        /// Points given.
        points: usize,
        /// Capacity.
        capacity: usize,
    },
    /// A coordinate is NaN or infinite.
    NonFinite {
        /// Index of the point.
        index: usize,
    },
}

impl core::fmt::Display for PathError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            PathError::Empty => write!(f, "path has no points"),
            PathError::TooLong { points, capacity } => {
                write!(f, "path has {points} points, the follower holds {capacity}")
            }
            PathError::NonFinite { index } => write!(f, "path point {index} is not finite"),
        }
    }
}

impl core::error::Error for PathError {}

/// One period's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FollowStep {
    /// Command this twist.
    Drive(Twist),
    /// Within tolerance of the last point: command zero.
    Arrived,
    /// No path loaded: command zero.
    NoPath,
}

/// Pure-pursuit follower over at most `N` points (fixed capacity, no heap).
#[derive(Debug, Clone)]
pub struct PathFollower<const N: usize> {
    config: FollowerConfig,
    path: Vec<[f32; 2], N>,
    /// Index of the segment the base is on (progress never goes backwards).
    segment: usize,
    /// Finish in line with the last segment ([`PathFollower::set_line`]).
    in_line: bool,
}

impl<const N: usize> PathFollower<N> {
    /// A follower with no path.
    pub const fn new(config: FollowerConfig) -> Self {
        Self {
            config,
            path: Vec::new(),
            segment: 0,
            in_line: false,
        }
    }

    /// Loads a path (world-frame points, m).
    pub fn set_path(&mut self, points: &[[f32; 2]]) -> Result<(), PathError> {
        if points.is_empty() {
            return Err(PathError::Empty);
        }
        if points.len() > N {
            return Err(PathError::TooLong {
                points: points.len(),
                capacity: N,
            });
        }
        if let Some(index) = points
            .iter()
            .position(|p| !p[0].is_finite() || !p[1].is_finite())
        {
            return Err(PathError::NonFinite { index });
        }
        self.path.clear();
        // Capacity was checked above, so every push fits.
        for p in points {
            let _ = self.path.push(*p);
        }
        self.segment = 0;
        self.in_line = false;
        Ok(())
    }

    /// Loads a straight line to drive in along (a docking): followed like a path, except that
    /// near its end a goal that lies more to the side than ahead (within half the look-ahead
    /// distance) counts as reached. A pose a few centimetres beside the goal, after a fix moved
    /// the estimate, would otherwise turn the base in place next to a table.
    pub fn set_line(&mut self, from: [f32; 2], to: [f32; 2]) -> Result<(), PathError> {
        self.set_path(&[from, to])?;
        self.in_line = true;
        Ok(())
    }

    /// Drops the path.
    pub fn clear(&mut self) {
        self.path.clear();
        self.segment = 0;
    }

    /// Remaining path length from the closest point, m.
    pub fn remaining_m(&self, pose: &Pose2F32) -> f32 {
        let Some(last) = self.path.last() else {
            return 0.0;
        };
        if self.path.len() == 1 {
            return dist([pose.x_m, pose.y_m], *last);
        }
        let (_, proj) = self.closest_on(self.segment, pose);
        let mut total = dist(proj, self.path[self.segment + 1]);
        for k in self.segment + 1..self.path.len() - 1 {
            total += dist(self.path[k], self.path[k + 1]);
        }
        total
    }

    fn closest_on(&self, k: usize, pose: &Pose2F32) -> (f32, [f32; 2]) {
        let a = self.path[k];
        let b = self.path[k + 1];
        let ab = [b[0] - a[0], b[1] - a[1]];
        let len2 = ab[0] * ab[0] + ab[1] * ab[1];
        let t = if len2 > 0.0 {
            (((pose.x_m - a[0]) * ab[0] + (pose.y_m - a[1]) * ab[1]) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let p = [a[0] + t * ab[0], a[1] + t * ab[1]];
        (dist(p, [pose.x_m, pose.y_m]), p)
    }

    /// The look-ahead point: `lookahead_m` along the path from the projection of the pose.
    fn lookahead_point(&self, pose: &Pose2F32) -> [f32; 2] {
        let last = self.path[self.path.len() - 1];
        if self.path.len() == 1 {
            return last;
        }
        let (_, mut from) = self.closest_on(self.segment, pose);
        let mut left = self.config.lookahead_m;
        for k in self.segment..self.path.len() - 1 {
            let to = self.path[k + 1];
            let d = dist(from, to);
            if d >= left && d > 0.0 {
                let t = left / d;
                return [
                    from[0] + t * (to[0] - from[0]),
                    from[1] + t * (to[1] - from[1]),
                ];
            }
            left -= d;
            from = to;
        }
        last
    }

    /// One control period at `pose`.
    pub fn step(&mut self, pose: &Pose2F32) -> FollowStep {
        let Some(&last) = self.path.last() else {
            return FollowStep::NoPath;
        };
        // Advance the segment while the next one is at least as close (monotonic progress).
        while self.segment + 2 < self.path.len() {
            let here = self.closest_on(self.segment, pose).0;
            let next = self.closest_on(self.segment + 1, pose).0;
            if next <= here {
                self.segment += 1;
            } else {
                break;
            }
        }
        let to_goal = dist([pose.x_m, pose.y_m], last);
        let remaining = self.remaining_m(pose).max(to_goal);
        if to_goal <= self.config.goal_tolerance_m {
            return FollowStep::Arrived;
        }

        let target = self.lookahead_point(pose);
        let dx = target[0] - pose.x_m;
        let dy = target[1] - pose.y_m;
        let (s, c) = (libm::sinf(pose.yaw_rad), libm::cosf(pose.yaw_rad));
        // Look-ahead point in the body frame.
        let x_b = c * dx + s * dy;
        let y_b = -s * dx + c * dy;
        let heading_error = wrap_angle_f32(libm::atan2f(y_b, x_b));
        let max_w = self.config.max_yaw_rate_radps;
        if heading_error.abs() > self.config.turn_in_place_above_rad {
            if self.in_line && to_goal <= ARRIVE_BESIDE_FACTOR * self.config.lookahead_m {
                // At the end of a docking line with the goal beside or behind (the estimate
                // moved sideways): stop here rather than turn in place next to the table.
                return FollowStep::Arrived;
            }
            return FollowStep::Drive(Twist::new(0.0, max_w.copysign(heading_error)));
        }
        // v = min(cruise, sqrt(2 a d)): can still stop at the goal with the decel limit.
        let stop_speed = libm::sqrtf(2.0 * self.config.stop_decel_mps2 * remaining);
        let mut v = self.config.cruise_speed_mps.min(stop_speed);
        let l2 = x_b * x_b + y_b * y_b;
        // Curvature 2 y / L^2 (pure pursuit), L the actual distance to the look-ahead point.
        let curvature = if l2 > 1e-9 { 2.0 * y_b / l2 } else { 0.0 };
        let mut w = v * curvature;
        if w.abs() > max_w {
            // Keep the arc, slow down along it.
            w = max_w.copysign(w);
            v = w / curvature;
        }
        FollowStep::Drive(Twist::new(v, w))
    }
}

fn dist(a: [f32; 2], b: [f32; 2]) -> f32 {
    libm::hypotf(b[0] - a[0], b[1] - a[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drive<const N: usize>(
        f: &mut PathFollower<N>,
        mut pose: Pose2F32,
        steps: usize,
    ) -> (Pose2F32, bool, f32) {
        let mut max_dev: f32 = 0.0;
        for _ in 0..steps {
            match f.step(&pose) {
                FollowStep::Drive(t) => {
                    pose = pose.advance(t.speed_mps * 0.02, t.yaw_rate_radps * 0.02)
                }
                FollowStep::Arrived => return (pose, true, max_dev),
                FollowStep::NoPath => return (pose, false, max_dev),
            }
            max_dev = max_dev.max(pose.y_m.abs().min((pose.x_m - 2.0).abs()));
        }
        (pose, false, max_dev)
    }

    #[test]
    fn finishes_a_docking_line_beside_the_goal_without_turning_in_place() {
        // A docking line: 1 m straight along -y. The estimate jumps 6 cm sideways 3 cm before
        // the goal (a fix arrives). A path's follower turns in place toward the goal point,
        // sweeping the footprint next to the table; a line's stops there instead.
        let run = |line: bool| {
            let mut f: PathFollower<8> = PathFollower::new(FollowerConfig::default());
            if line {
                f.set_line([0.0, 1.0], [0.0, 0.0]).unwrap();
            } else {
                f.set_path(&[[0.0, 1.0], [0.0, 0.0]]).unwrap();
            }
            let mut pose = Pose2F32::new(0.06, 0.03, -core::f32::consts::FRAC_PI_2);
            let mut worst_turn: f32 = 0.0;
            for _ in 0..500 {
                match f.step(&pose) {
                    FollowStep::Drive(t) => {
                        pose = pose.advance(t.speed_mps * 0.02, t.yaw_rate_radps * 0.02)
                    }
                    FollowStep::Arrived => return (true, worst_turn, pose),
                    FollowStep::NoPath => break,
                }
                worst_turn = worst_turn
                    .max(wrap_angle_f32(pose.yaw_rad + core::f32::consts::FRAC_PI_2).abs());
            }
            (false, worst_turn, pose)
        };
        let (arrived, worst_turn, pose) = run(true);
        assert!(arrived, "never arrived: {pose:?}");
        assert!(worst_turn < 0.1, "turned {worst_turn} rad off the line");
        assert!(libm::hypotf(pose.x_m, pose.y_m) <= 0.07, "{pose:?}");
        let (arrived, worst_turn, _) = run(false);
        assert!(
            arrived && worst_turn > 0.5,
            "a path turns to its goal: {worst_turn}"
        );
        // A line whose goal is still ahead is driven as a path.
        let mut f: PathFollower<8> = PathFollower::new(FollowerConfig::default());
        f.set_line([0.0, 1.0], [0.0, 0.0]).unwrap();
        let ahead = Pose2F32::new(0.06, 0.5, -core::f32::consts::FRAC_PI_2);
        assert!(matches!(f.step(&ahead), FollowStep::Drive(_)));
    }

    #[test]
    fn follows_an_l_shaped_path_to_the_goal() {
        let mut f: PathFollower<16> = PathFollower::new(FollowerConfig::default());
        f.set_path(&[[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]]).unwrap();
        let (pose, arrived, max_dev) = drive(&mut f, Pose2F32::default(), 2000);
        assert!(arrived, "did not arrive: {pose:?}");
        assert!(libm::hypotf(pose.x_m - 2.0, pose.y_m - 2.0) <= 0.05);
        // Corner cutting stays within the look-ahead distance.
        assert!(max_dev < 0.3, "{max_dev}");
    }

    #[test]
    fn turns_in_place_when_the_path_is_behind() {
        let mut f: PathFollower<4> = PathFollower::new(FollowerConfig::default());
        f.set_path(&[[0.0, 0.0], [-2.0, 0.0]]).unwrap();
        match f.step(&Pose2F32::default()) {
            FollowStep::Drive(t) => {
                assert_eq!(t.speed_mps, 0.0);
                assert_eq!(t.yaw_rate_radps.abs(), 1.0);
            }
            other => panic!("{other:?}"),
        }
        let (_, arrived, _) = drive(&mut f, Pose2F32::default(), 2000);
        assert!(arrived);
    }

    #[test]
    fn slows_down_before_the_goal_and_rejects_bad_paths() {
        let mut f: PathFollower<4> = PathFollower::new(FollowerConfig::default());
        f.set_path(&[[0.0, 0.0], [1.0, 0.0]]).unwrap();
        let FollowStep::Drive(far) = f.step(&Pose2F32::default()) else {
            panic!()
        };
        let FollowStep::Drive(near) = f.step(&Pose2F32::new(0.9, 0.0, 0.0)) else {
            panic!()
        };
        assert_eq!(far.speed_mps, 0.4);
        assert!(near.speed_mps < 0.35);
        assert_eq!(f.set_path(&[]), Err(PathError::Empty));
        assert_eq!(
            f.set_path(&[[0.0, 0.0]; 5]),
            Err(PathError::TooLong {
                points: 5,
                capacity: 4
            })
        );
        assert_eq!(
            f.set_path(&[[0.0, f32::NAN]]),
            Err(PathError::NonFinite { index: 0 })
        );
        f.clear();
        assert_eq!(f.step(&Pose2F32::default()), FollowStep::NoPath);
    }
}
