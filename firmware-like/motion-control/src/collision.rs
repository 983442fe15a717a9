//! The collision monitor: the last law before the base driver. It reads raw range points (no
//! costmap, no map), the base's footprint and the commanded twist, and returns the twist it
//! lets through with the action that shaped it.
//!
//! Modelled on Nav2's collision monitor (a stop zone, a slowdown zone, an approach check that
//! projects the footprint along the command) with three differences that its users ask for:
//!
//! * **Escape.** A stop zone that holds a point stops every motion *toward* it; a command that
//!   increases the clearance of the nearest points over the next simulation step may still move,
//!   at docking speed. A robot that stops next to a chair can back away from it instead of
//!   waiting for an operator.
//! * **Docking shape.** In [`MonitorMode::Docking`] (the last metres to a standing spot next to
//!   the table, where the plan itself stands within centimetres of chairs) the stop zone shrinks
//!   to [`MonitorConfig::docking_margin_m`] and the twist is capped at crawl speed, so that the
//!   robot can dock without the monitor's margin forbidding the spot.
//! * **Stale means blocked.** No scan, or a scan older than [`MonitorConfig::scan_timeout_us`],
//!   is an obstacle everywhere: zero twist, [`Action::Stale`].
//!
//! The points are reduced per revolution to the nearest return in each of [`BINS`] bearings
//! ([`Obstacles`]): the footprint is convex and contains the base centre, so along one bearing
//! a farther point can only be inside a zone if the nearest is. The approach check of a moving
//! footprint uses the same reduction; its error is at most the bin's arc (0.5 deg: 2.6 cm at
//! 3 m), far below the zones' margins at the ranges where the approach check acts.
//!
//! It is not a certified safety function; a real robot also needs a hardware e-stop chain and
//! a safety-rated scanner on the base's safety inputs.

use planar::Pose2F32;

use crate::Twist;

/// Bearing bins of an [`Obstacles`] set (0.5 deg each).
pub const BINS: usize = 720;

const BIN_RAD: f32 = 2.0 * core::f32::consts::PI / BINS as f32;

/// The nearest obstacle point per bearing, in the base frame (x forward, y left), projected on
/// the floor. Fixed size, no heap.
#[derive(Debug, Clone)]
pub struct Obstacles {
    points: [[f32; 2]; BINS],
    range2: [f32; BINS],
    occupied: u16,
    stamp_us: u64,
    dropped_own_body: u32,
}

impl Default for Obstacles {
    fn default() -> Self {
        Self::new()
    }
}

impl Obstacles {
    /// An empty set (no obstacle; note that an empty set is not a fresh scan: see
    /// [`CollisionMonitor::set_scan`]).
    pub const fn new() -> Self {
        Self {
            points: [[0.0; 2]; BINS],
            range2: [f32::INFINITY; BINS],
            occupied: 0,
            stamp_us: 0,
            dropped_own_body: 0,
        }
    }

    /// Empties the set for a new scan taken at `stamp_us`.
    pub fn clear(&mut self, stamp_us: u64) {
        self.range2 = [f32::INFINITY; BINS];
        self.occupied = 0;
        self.stamp_us = stamp_us;
        self.dropped_own_body = 0;
    }

    /// The time of the scan (the monitor's clock, microseconds).
    pub fn stamp_us(&self) -> u64 {
        self.stamp_us
    }

    /// Bearings holding a point.
    pub fn len(&self) -> usize {
        usize::from(self.occupied)
    }

    /// True when no bearing holds a point.
    pub fn is_empty(&self) -> bool {
        self.occupied == 0
    }

    /// Points dropped because they lay inside the robot's own footprint (its body, the arm
    /// column) since the last [`Obstacles::clear`].
    pub fn dropped_own_body(&self) -> u32 {
        self.dropped_own_body
    }

    /// Adds a point (base frame, metres); keeps it if it is the nearest of its bearing. Points
    /// inside `own` (the robot's body: half length, half width) are the robot itself and are
    /// dropped (counted). Non-finite points are ignored.
    pub fn add(&mut self, x: f32, y: f32, own: [f32; 2]) {
        if !x.is_finite() || !y.is_finite() {
            return;
        }
        if x.abs() <= own[0] && y.abs() <= own[1] {
            self.dropped_own_body = self.dropped_own_body.saturating_add(1);
            return;
        }
        let bin = bin_of(x, y);
        let r2 = x * x + y * y;
        if r2 < self.range2[bin] {
            if self.range2[bin] == f32::INFINITY {
                self.occupied += 1;
            }
            self.range2[bin] = r2;
            self.points[bin] = [x, y];
        }
    }

    /// The kept points, one per occupied bearing.
    pub fn iter(&self) -> impl Iterator<Item = [f32; 2]> + '_ {
        self.range2
            .iter()
            .zip(self.points.iter())
            .filter(|(r2, _)| r2.is_finite())
            .map(|(_, p)| *p)
    }

    /// Moves every kept point into the frame of a base that has since moved by `motion`
    /// (the new base pose expressed in the old base frame): deskews a scan by odometry. Bins
    /// are not recomputed (a few centimetres of motion move a point by less than a bin at the
    /// ranges that matter). The stamp stays the scan's: moving old points does not make them
    /// fresh.
    pub fn move_base(&mut self, motion: Pose2F32) {
        let (s, c) = (libm::sinf(motion.yaw_rad), libm::cosf(motion.yaw_rad));
        for (p, r2) in self.points.iter_mut().zip(self.range2.iter_mut()) {
            if r2.is_finite() {
                let dx = p[0] - motion.x_m;
                let dy = p[1] - motion.y_m;
                *p = [c * dx + s * dy, -s * dx + c * dy];
                *r2 = p[0] * p[0] + p[1] * p[1];
            }
        }
    }
}

fn bin_of(x: f32, y: f32) -> usize {
    let a = libm::atan2f(y, x) + core::f32::consts::PI; // 0..=2 pi
    let b = (a / BIN_RAD) as usize;
    b.min(BINS - 1)
}

/// The monitor's settings. Zones are the footprint grown by a margin on every side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonitorConfig {
    /// Half the footprint's length along the heading (m).
    pub half_length_m: f32,
    /// Half the footprint's width (m).
    pub half_width_m: f32,
    /// Stop zone: the footprint grown by this (m).
    pub stop_margin_m: f32,
    /// Slowdown zone: the footprint grown by this (m).
    pub slowdown_margin_m: f32,
    /// Speed factor in the slowdown zone.
    pub slowdown_ratio: f32,
    /// Approach: the command is scaled so that the stop zone is never reached sooner than
    /// this (s).
    pub time_before_collision_s: f32,
    /// Approach: the projection's time step (s).
    pub simulation_step_s: f32,
    /// Docking: the stop zone's margin in the last metres to a standing spot (m).
    pub docking_margin_m: f32,
    /// Docking (and escaping a stop zone): the highest speed (m/s).
    pub docking_speed_mps: f32,
    /// Docking (and escaping a stop zone): the highest yaw rate (rad/s).
    pub docking_yaw_rate_radps: f32,
    /// Docking: the approach check's time before collision (s); shorter than driving's, so
    /// that the base closes in to the docking shape instead of creeping forever.
    pub docking_time_before_collision_s: f32,
    /// Bearings with a point a zone needs before it acts (filters single noisy returns).
    pub min_points: u16,
    /// A scan older than this is no scan (us).
    pub scan_timeout_us: u64,
}

impl MonitorConfig {
    /// The defaults for a footprint of `length_m` x `width_m`: a 2 cm stop zone, a 15 cm
    /// slowdown zone at half speed, 1.0 s before collision, a 1 cm docking shape at 8 cm/s (0.25 s before collision), two
    /// bearings, a 250 ms scan timeout (two and a half revolutions at 10 Hz).
    pub fn for_footprint(length_m: f32, width_m: f32) -> Self {
        Self {
            half_length_m: 0.5 * length_m,
            half_width_m: 0.5 * width_m,
            stop_margin_m: 0.02,
            slowdown_margin_m: 0.15,
            slowdown_ratio: 0.5,
            time_before_collision_s: 1.0,
            simulation_step_s: 0.05,
            docking_margin_m: 0.01,
            docking_speed_mps: 0.08,
            docking_yaw_rate_radps: 0.3,
            docking_time_before_collision_s: 0.25,
            min_points: 2,
            scan_timeout_us: 250_000,
        }
    }

    /// The own-body box for [`Obstacles::add`].
    pub fn own_body(&self) -> [f32; 2] {
        [self.half_length_m, self.half_width_m]
    }
}

/// Which shapes act.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MonitorMode {
    /// Driving between spots: full stop zone, slowdown, approach.
    #[default]
    Normal,
    /// The last metres to a standing spot: the reduced docking shape at crawl speed.
    Docking,
}

/// What shaped the twist, most severe last.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
pub enum Action {
    /// Nothing in any zone.
    #[default]
    Clear,
    /// Capped at docking speed (docking mode, or escaping a stop zone).
    Crawl,
    /// Points in the slowdown zone: scaled by the slowdown ratio.
    Slowdown,
    /// The projected footprint meets the stop zone within the time before collision: scaled.
    Approach,
    /// Points in the stop zone and the command does not move away from them: zero.
    Stop,
    /// No scan, or a scan older than the timeout: zero.
    Stale,
}

/// The monitor's answer for one command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Verdict {
    /// The twist let through.
    pub twist: Twist,
    /// What shaped it.
    pub action: Action,
    /// Clearance between the footprint and the nearest point (m; negative inside; infinite
    /// with no point).
    pub clearance_m: f32,
    /// Bearings inside the acting zone (stop or slowdown), or at the projected contact.
    pub points: u16,
}

/// The collision monitor: holds the latest scan's obstacles and checks commands against them.
#[derive(Debug, Clone)]
pub struct CollisionMonitor {
    config: MonitorConfig,
    obstacles: Obstacles,
    has_scan: bool,
}

impl CollisionMonitor {
    /// A monitor with no scan yet (so everything is [`Action::Stale`]).
    pub fn new(config: MonitorConfig) -> Self {
        Self {
            config,
            obstacles: Obstacles::new(),
            has_scan: false,
        }
    }

    /// The settings.
    pub fn config(&self) -> &MonitorConfig {
        &self.config
    }

    /// Takes a new scan's obstacles (a copy into the monitor's own set).
    pub fn set_scan(&mut self, obstacles: &Obstacles) {
        self.obstacles.clone_from(obstacles);
        self.has_scan = true;
    }

    /// The current obstacles, for deskewing by odometry ([`Obstacles::move_base`]).
    pub fn obstacles_mut(&mut self) -> Option<&mut Obstacles> {
        self.has_scan.then_some(&mut self.obstacles)
    }

    /// The current obstacles.
    pub fn obstacles(&self) -> Option<&Obstacles> {
        self.has_scan.then_some(&self.obstacles)
    }

    /// Forgets the scan (stale until the next).
    pub fn forget_scan(&mut self) {
        self.has_scan = false;
    }

    /// Checks `command` at `now_us` and returns the twist to send.
    pub fn check(&self, command: Twist, mode: MonitorMode, now_us: u64) -> Verdict {
        let cfg = &self.config;
        let stale = !self.has_scan
            || now_us.saturating_sub(self.obstacles.stamp_us) > cfg.scan_timeout_us
            || !command.is_finite();
        if stale {
            return Verdict {
                twist: Twist::ZERO,
                action: Action::Stale,
                clearance_m: f32::NEG_INFINITY,
                points: 0,
            };
        }
        let stop_margin = match mode {
            MonitorMode::Normal => cfg.stop_margin_m,
            MonitorMode::Docking => cfg.docking_margin_m,
        };
        let (hl, hw) = (cfg.half_length_m, cfg.half_width_m);
        let mut in_stop = 0u16;
        let mut in_slow = 0u16;
        let mut clearance = f32::INFINITY;
        for [x, y] in self.obstacles.iter() {
            let d = signed_distance(x, y, hl, hw);
            clearance = clearance.min(d);
            if d <= stop_margin {
                in_stop += 1;
            } else if d <= cfg.slowdown_margin_m {
                in_slow += 1;
            }
        }
        let moving = command.speed_mps != 0.0 || command.yaw_rate_radps != 0.0;
        let crawl = |t: Twist| {
            Twist::new(
                t.speed_mps
                    .clamp(-cfg.docking_speed_mps, cfg.docking_speed_mps),
                t.yaw_rate_radps
                    .clamp(-cfg.docking_yaw_rate_radps, cfg.docking_yaw_rate_radps),
            )
        };
        if in_stop >= cfg.min_points {
            // Escape: allowed only if, one step on at crawl speed, the nearest point is farther.
            let slow = crawl(command);
            let after = slow.motion_over(cfg.simulation_step_s);
            let escapes = moving && self.min_clearance_at(after) > clearance + 1e-4;
            return if escapes {
                Verdict {
                    twist: slow,
                    action: Action::Crawl,
                    clearance_m: clearance,
                    points: in_stop,
                }
            } else {
                Verdict {
                    twist: Twist::ZERO,
                    action: Action::Stop,
                    clearance_m: clearance,
                    points: in_stop,
                }
            };
        }
        let mut twist = command;
        let mut action = Action::Clear;
        let mut points = 0u16;
        if mode == MonitorMode::Docking {
            let capped = crawl(twist);
            if capped != twist {
                twist = capped;
                action = Action::Crawl;
            }
        } else if in_slow >= cfg.min_points {
            twist = Twist::new(
                twist.speed_mps * cfg.slowdown_ratio,
                twist.yaw_rate_radps * cfg.slowdown_ratio,
            );
            action = Action::Slowdown;
            points = in_slow;
        }
        let horizon = match mode {
            MonitorMode::Normal => cfg.time_before_collision_s,
            MonitorMode::Docking => cfg.docking_time_before_collision_s,
        };
        if moving && let Some((t_hit, hits)) = self.first_contact(twist, stop_margin, horizon) {
            let scale = ((t_hit - cfg.simulation_step_s) / horizon).max(0.0);
            if scale < 1.0 {
                twist = Twist::new(twist.speed_mps * scale, twist.yaw_rate_radps * scale);
                action = action.max(Action::Approach);
                points = hits;
            }
        }
        Verdict {
            twist,
            action,
            clearance_m: clearance,
            points,
        }
    }

    /// The smallest signed distance between the footprint at `pose` (in the current base frame)
    /// and the kept points.
    fn min_clearance_at(&self, pose: Pose2F32) -> f32 {
        let (s, c) = (libm::sinf(pose.yaw_rad), libm::cosf(pose.yaw_rad));
        let (hl, hw) = (self.config.half_length_m, self.config.half_width_m);
        self.obstacles
            .iter()
            .map(|[x, y]| {
                let (dx, dy) = (x - pose.x_m, y - pose.y_m);
                signed_distance(c * dx + s * dy, -s * dx + c * dy, hl, hw)
            })
            .fold(f32::INFINITY, f32::min)
    }

    /// The first time within the time before collision at which the footprint, moved along
    /// `twist`, has `min_points` points within `margin`; with their count.
    fn first_contact(&self, twist: Twist, margin: f32, horizon: f32) -> Option<(f32, u16)> {
        let cfg = &self.config;
        let step = cfg.simulation_step_s.max(1e-3);
        let horizon = horizon.max(step);
        // Points farther than anything the footprint can reach in the horizon are skipped.
        let reach = libm::sqrtf(
            cfg.half_length_m * cfg.half_length_m + cfg.half_width_m * cfg.half_width_m,
        ) + margin
            + twist.speed_mps.abs() * horizon;
        let reach2 = reach * reach;
        let (hl, hw) = (cfg.half_length_m + margin, cfg.half_width_m + margin);
        let steps = libm::ceilf(horizon / step) as u32;
        for k in 1..=steps {
            let t = step * k as f32;
            let pose = twist.motion_over(t);
            let (s, c) = (libm::sinf(pose.yaw_rad), libm::cosf(pose.yaw_rad));
            let mut hits = 0u16;
            for [x, y] in self.obstacles.iter() {
                if x * x + y * y > reach2 {
                    continue;
                }
                let (dx, dy) = (x - pose.x_m, y - pose.y_m);
                let (u, v) = (c * dx + s * dy, -s * dx + c * dy);
                if u.abs() <= hl && v.abs() <= hw {
                    hits += 1;
                }
            }
            if hits >= cfg.min_points {
                return Some((t, hits));
            }
        }
        None
    }
}

/// Signed distance from a point to the rectangle |x| <= hl, |y| <= hw (negative inside).
pub fn signed_distance(x: f32, y: f32, hl: f32, hw: f32) -> f32 {
    let dx = x.abs() - hl;
    let dy = y.abs() - hw;
    if dx <= 0.0 && dy <= 0.0 {
        dx.max(dy)
    } else {
        let ox = dx.max(0.0);
        let oy = dy.max(0.0);
        libm::sqrtf(ox * ox + oy * oy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOW: u64 = 1_000_000;

    fn monitor_with(points: &[[f32; 2]]) -> CollisionMonitor {
        let cfg = MonitorConfig::for_footprint(0.6, 0.55);
        let mut obstacles = Obstacles::new();
        obstacles.clear(NOW);
        for p in points {
            obstacles.add(p[0], p[1], cfg.own_body());
        }
        let mut m = CollisionMonitor::new(cfg);
        m.set_scan(&obstacles);
        m
    }

    /// A wall of points across the heading at x = `x`, 1 cm apart.
    fn wall_at(x: f32) -> [[f32; 2]; 101] {
        core::array::from_fn(|i| [x, -0.5 + 0.01 * i as f32])
    }

    #[test]
    fn no_scan_or_an_old_scan_is_an_obstacle() {
        let m = CollisionMonitor::new(MonitorConfig::for_footprint(0.6, 0.55));
        let v = m.check(Twist::new(0.3, 0.0), MonitorMode::Normal, NOW);
        assert_eq!((v.twist, v.action), (Twist::ZERO, Action::Stale));
        let m = monitor_with(&[]);
        assert_eq!(
            m.check(Twist::new(0.3, 0.0), MonitorMode::Normal, NOW + 100_000)
                .action,
            Action::Clear
        );
        let v = m.check(Twist::new(0.3, 0.0), MonitorMode::Normal, NOW + 250_001);
        assert_eq!((v.twist, v.action), (Twist::ZERO, Action::Stale));
    }

    #[test]
    fn a_point_in_the_stop_zone_stops_motion_toward_it_and_lets_the_base_back_away() {
        // Footprint front at 0.30 m; wall at 0.315 m: inside the 2 cm stop zone.
        let m = monitor_with(&wall_at(0.315));
        let v = m.check(Twist::new(0.3, 0.0), MonitorMode::Normal, NOW);
        assert_eq!((v.twist, v.action), (Twist::ZERO, Action::Stop));
        assert!((v.clearance_m - 0.015).abs() < 1e-4, "{v:?}");
        // Backing away is allowed at crawl speed.
        let v = m.check(Twist::new(-0.3, 0.0), MonitorMode::Normal, NOW);
        assert_eq!(v.action, Action::Crawl);
        assert_eq!(v.twist.speed_mps, -0.08);
        // Standing still is a stop, not an escape.
        assert_eq!(
            m.check(Twist::ZERO, MonitorMode::Normal, NOW).action,
            Action::Stop
        );
    }

    #[test]
    fn one_noisy_return_does_not_stop_the_base() {
        let m = monitor_with(&[[0.31, 0.0]]);
        let v = m.check(Twist::new(0.2, 0.0), MonitorMode::Normal, NOW);
        assert_ne!(v.action, Action::Stop);
    }

    #[test]
    fn the_slowdown_zone_scales_and_the_approach_check_slows_before_contact() {
        // Wall 0.1 m ahead of the front: slowdown zone (0.02..0.15).
        let m = monitor_with(&wall_at(0.4));
        let v = m.check(Twist::new(0.1, 0.0), MonitorMode::Normal, NOW);
        assert!(v.action >= Action::Slowdown, "{v:?}");
        assert!(v.twist.speed_mps <= 0.05 + 1e-6, "{v:?}");
        // Wall 0.5 m ahead of the front at 0.4 m/s: the stop zone is 0.48 m away, 1.2 s: clear;
        // at 0.8 m/s it would be reached in 0.6 s: scaled.
        let m = monitor_with(&wall_at(0.8));
        let v = m.check(Twist::new(0.8, 0.0), MonitorMode::Normal, NOW);
        assert_eq!(v.action, Action::Approach, "{v:?}");
        assert!(v.twist.speed_mps < 0.8 && v.twist.speed_mps > 0.2, "{v:?}");
        // Driving away from the same wall is not touched.
        let v = m.check(Twist::new(-0.4, 0.0), MonitorMode::Normal, NOW);
        assert_eq!(v.twist, Twist::new(-0.4, 0.0));
    }

    #[test]
    fn turning_in_place_next_to_a_chair_corner_is_checked_too() {
        // Points just ahead of the front edge near its left corner: turning right swings the
        // front edge's left half into them; turning left swings it away.
        let m = monitor_with(&[[0.36, 0.2], [0.36, 0.21]]);
        let v = m.check(Twist::new(0.0, -1.0), MonitorMode::Normal, NOW);
        assert_eq!(v.action, Action::Approach, "{v:?}");
        assert!(v.twist.yaw_rate_radps > -0.5, "{v:?}");
        let v = m.check(Twist::new(0.0, 1.0), MonitorMode::Normal, NOW);
        assert_eq!((v.action, v.twist.yaw_rate_radps), (Action::Slowdown, 0.5));
    }

    #[test]
    fn docking_uses_the_reduced_shape_at_crawl_speed() {
        // 1.5 cm ahead: a stop in normal mode; docking may still close in (slowing as it
        // nears the 1 cm shape).
        let m = monitor_with(&wall_at(0.315));
        assert_eq!(
            m.check(Twist::new(0.05, 0.0), MonitorMode::Normal, NOW)
                .action,
            Action::Stop
        );
        let v = m.check(Twist::new(0.05, 0.0), MonitorMode::Docking, NOW);
        assert!(
            v.action < Action::Stop && v.twist.speed_mps > 0.005,
            "{v:?}"
        );
        // 0.5 cm: inside the docking shape too.
        let m = monitor_with(&wall_at(0.305));
        let v = m.check(Twist::new(0.05, 0.0), MonitorMode::Docking, NOW);
        assert_eq!(v.action, Action::Stop);
        // Docking caps the speed even with nothing near.
        let m = monitor_with(&[]);
        let v = m.check(Twist::new(0.4, 0.0), MonitorMode::Docking, NOW);
        assert_eq!((v.twist.speed_mps, v.action), (0.08, Action::Crawl));
    }

    #[test]
    fn own_body_points_are_dropped_and_nearest_per_bearing_kept() {
        let mut o = Obstacles::new();
        o.clear(0);
        o.add(0.1, 0.1, [0.3, 0.275]);
        o.add(2.0, 0.0, [0.3, 0.275]);
        o.add(1.0, 0.0, [0.3, 0.275]);
        o.add(f32::NAN, 0.0, [0.3, 0.275]);
        assert_eq!(o.dropped_own_body(), 1);
        assert_eq!(o.len(), 1);
        assert_eq!(o.iter().next(), Some([1.0, 0.0]));
    }

    #[test]
    fn deskewing_moves_points_into_the_new_base_frame() {
        let mut o = Obstacles::new();
        o.clear(0);
        o.add(1.0, 0.0, [0.3, 0.275]);
        o.move_base(Pose2F32::new(0.1, 0.0, core::f32::consts::FRAC_PI_2));
        let p = o.iter().next().unwrap();
        assert!(
            (p[0] - 0.0).abs() < 1e-5 && (p[1] + 0.9).abs() < 1e-5,
            "{p:?}"
        );
        assert_eq!(
            o.stamp_us(),
            0,
            "moving old points does not make them fresh"
        );
    }

    #[test]
    fn signed_distance_inside_and_outside() {
        assert!((signed_distance(0.0, 0.0, 0.3, 0.2) + 0.2).abs() < 1e-6);
        assert!((signed_distance(0.4, 0.0, 0.3, 0.2) - 0.1).abs() < 1e-6);
        assert!((signed_distance(0.6, 0.6, 0.3, 0.2) - 0.5).abs() < 1e-6);
    }
}
