//! Where the base is in the map: wheel odometry between fixes, corrected by the localiser's
//! fixes on `base/pose`.
//!
//! Odometry is smooth but drifts; fixes do not drift but jump and arrive at a few Hz. The
//! estimate is the odometry pose carried into the map by a correction transform; each global
//! fix pulls the correction a fraction `fix_gain` of the way towards agreeing with the fix (a
//! complementary filter: odometry passes at high frequency, fixes at low), which keeps the
//! follower's input smooth. A table-relative fix (a table-edge detector, centimetre-precise,
//! valid only at the table) replaces the estimate outright and is what the arm plans with.

use planar::{Pose2, wrap_angle};

/// Settings of the filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocaliserConfig {
    /// Fraction of the disagreement with a global fix removed per fix (0..=1).
    pub fix_gain: f64,
    /// A global fix farther than this from the estimate is a jump: taken whole (the estimate
    /// was wrong, e.g. after a kidnap) and reported.
    pub jump_m: f64,
    /// No global fix for this long (ns) and the estimate is stale: the base must not drive.
    pub stale_after_ns: u64,
}

impl Default for LocaliserConfig {
    fn default() -> Self {
        Self {
            fix_gain: 0.3,
            jump_m: 0.5,
            stale_after_ns: 1_000_000_000,
        }
    }
}

/// What a fix did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FixOutcome {
    /// Blended in.
    Blended,
    /// Far from the estimate: taken whole.
    Jumped {
        /// How far the estimate moved, m.
        by_m: f64,
    },
    /// Not finite or older than the last one: ignored.
    Rejected,
}

/// Odometry + fixes.
#[derive(Debug, Clone)]
pub struct Localiser {
    config: LocaliserConfig,
    /// Map pose of the odometry frame's origin.
    map_from_odom: Pose2,
    odom: Pose2,
    initialised: bool,
    last_global_ns: Option<u64>,
    table_fix: Option<(Pose2, u64)>,
    odom_at_table_fix: Pose2,
    last_aligned_ns: Option<u64>,
}

/// After a scan alignment, global fixes do not move the estimate for this long (ns).
pub const ALIGNED_FOR_NS: u64 = 1_000_000_000;

impl Localiser {
    /// A filter that knows nothing yet.
    pub fn new(config: LocaliserConfig) -> Self {
        Self {
            config,
            map_from_odom: Pose2::default(),
            odom: Pose2::default(),
            initialised: false,
            last_global_ns: None,
            table_fix: None,
            odom_at_table_fix: Pose2::default(),
            last_aligned_ns: None,
        }
    }

    /// New odometry pose (the driver's dead reckoning, its own frame).
    pub fn on_odometry(&mut self, odom: Pose2) {
        if odom.is_finite() {
            self.odom = odom;
        }
    }

    /// A global fix measured at `stamp_ns`.
    pub fn on_global_fix(&mut self, fix: Pose2, stamp_ns: u64) -> FixOutcome {
        if !fix.is_finite() || self.last_global_ns.is_some_and(|t| stamp_ns < t) {
            return FixOutcome::Rejected;
        }
        self.last_global_ns = Some(stamp_ns);
        if self.initialised && self.is_aligned(stamp_ns) {
            // The scan alignment is the better source while it lasts.
            return FixOutcome::Blended;
        }
        // The correction that would make the estimate equal the fix.
        let wanted = fix.compose(&self.odom.inverse());
        if !self.initialised {
            self.map_from_odom = wanted;
            self.initialised = true;
            return FixOutcome::Jumped { by_m: 0.0 };
        }
        let estimate = self.estimate();
        let off = estimate.distance_m(&fix);
        if off > self.config.jump_m {
            self.map_from_odom = wanted;
            return FixOutcome::Jumped { by_m: off };
        }
        let g = self.config.fix_gain.clamp(0.0, 1.0);
        // Blend the estimate towards the fix, then express it as a correction again.
        let blended = Pose2 {
            x_m: estimate.x_m + g * (fix.x_m - estimate.x_m),
            y_m: estimate.y_m + g * (fix.y_m - estimate.y_m),
            yaw_rad: wrap_angle(estimate.yaw_rad + g * wrap_angle(fix.yaw_rad - estimate.yaw_rad)),
        };
        self.map_from_odom = blended.compose(&self.odom.inverse());
        FixOutcome::Blended
    }

    /// A scan-to-map alignment: `pose` is where the base was when the odometry read `odom`.
    /// Pulls the correction half way to it (the alignment is centimetre-precise but can be
    /// fooled by moved furniture; two agreeing scans make it whole). While alignments arrive
    /// (within [`ALIGNED_FOR_NS`]), global fixes keep the estimate fresh but no longer move it:
    /// their per-leg bias is what the alignment removes.
    pub fn on_aligned(&mut self, pose: Pose2, odom: Pose2, stamp_ns: u64) -> FixOutcome {
        if !pose.is_finite() || !odom.is_finite() || !self.initialised {
            return FixOutcome::Rejected;
        }
        let wanted = pose.compose(&odom.inverse());
        let now_estimate = self.estimate();
        let target = wanted.compose(&self.odom);
        let g = 0.5;
        let blended = Pose2 {
            x_m: now_estimate.x_m + g * (target.x_m - now_estimate.x_m),
            y_m: now_estimate.y_m + g * (target.y_m - now_estimate.y_m),
            yaw_rad: wrap_angle(
                now_estimate.yaw_rad + g * wrap_angle(target.yaw_rad - now_estimate.yaw_rad),
            ),
        };
        self.map_from_odom = blended.compose(&self.odom.inverse());
        self.last_aligned_ns = Some(stamp_ns);
        FixOutcome::Blended
    }

    /// Whether a scan alignment was taken within [`ALIGNED_FOR_NS`] of `now_ns`.
    pub fn is_aligned(&self, now_ns: u64) -> bool {
        self.last_aligned_ns
            .is_some_and(|t| now_ns.saturating_sub(t) <= ALIGNED_FOR_NS)
    }

    /// A table-relative fix (already in the world frame): taken whole, and kept as the arm's
    /// pose until the base moves.
    pub fn on_table_fix(&mut self, fix: Pose2, stamp_ns: u64) -> FixOutcome {
        if !fix.is_finite() {
            return FixOutcome::Rejected;
        }
        let by_m = if self.initialised {
            self.estimate().distance_m(&fix)
        } else {
            0.0
        };
        self.map_from_odom = fix.compose(&self.odom.inverse());
        self.initialised = true;
        self.table_fix = Some((fix, stamp_ns));
        self.odom_at_table_fix = self.odom;
        FixOutcome::Jumped { by_m }
    }

    /// The table-relative pose, if one was measured after `since_ns` and the base has not
    /// moved (by odometry, 5 mm / 0.01 rad) since.
    pub fn table_pose(&self, since_ns: u64) -> Option<Pose2> {
        let (pose, stamp) = self.table_fix?;
        let moved = self.odom.distance_m(&self.odom_at_table_fix) > 0.005
            || wrap_angle(self.odom.yaw_rad - self.odom_at_table_fix.yaw_rad).abs() > 0.01;
        (stamp >= since_ns && !moved).then_some(pose)
    }

    /// The pose estimate in the map.
    pub fn estimate(&self) -> Pose2 {
        self.map_from_odom.compose(&self.odom)
    }

    /// Whether a fix ever arrived.
    pub fn is_initialised(&self) -> bool {
        self.initialised
    }

    /// Whether global fixes stopped arriving (or never did) at `now_ns`.
    pub fn is_stale(&self, now_ns: u64) -> bool {
        match self.last_global_ns {
            Some(t) => now_ns.saturating_sub(t) > self.config.stale_after_ns,
            None => true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Pose2, b: Pose2, tol: f64) -> bool {
        a.distance_m(&b) < tol && wrap_angle(a.yaw_rad - b.yaw_rad).abs() < tol
    }

    #[test]
    fn compose_and_inverse_round_trip() {
        let a = Pose2::new(1.0, -2.0, 0.7);
        let b = Pose2::new(0.3, 0.4, -1.2);
        let ab = a.compose(&b);
        assert!(close(a.inverse().compose(&ab), b, 1e-9));
        assert!(close(a.compose(&a.inverse()), Pose2::default(), 1e-9));
    }

    #[test]
    fn first_fix_places_the_odometry_frame_then_odometry_moves_the_estimate() {
        let mut loc = Localiser::new(LocaliserConfig::default());
        assert!(loc.is_stale(0));
        loc.on_odometry(Pose2::new(5.0, 5.0, 0.0));
        loc.on_global_fix(Pose2::new(1.0, 2.0, std::f64::consts::FRAC_PI_2), 10);
        assert!(close(
            loc.estimate(),
            Pose2::new(1.0, 2.0, std::f64::consts::FRAC_PI_2),
            1e-9
        ));
        // One metre forward in odometry = one metre along +y in the map.
        loc.on_odometry(Pose2::new(6.0, 5.0, 0.0));
        assert!(close(
            loc.estimate(),
            Pose2::new(1.0, 3.0, std::f64::consts::FRAC_PI_2),
            1e-9
        ));
        assert!(!loc.is_stale(10 + 500_000_000));
        assert!(loc.is_stale(10 + 2_000_000_000));
    }

    #[test]
    fn repeated_fixes_converge_and_jumps_are_taken_whole() {
        let mut loc = Localiser::new(LocaliserConfig::default());
        loc.on_global_fix(Pose2::new(0.0, 0.0, 0.0), 1);
        let truth = Pose2::new(0.2, -0.1, 0.05);
        for k in 0..40 {
            assert_ne!(loc.on_global_fix(truth, 2 + k), FixOutcome::Rejected);
        }
        assert!(close(loc.estimate(), truth, 1e-5));
        let far = Pose2::new(3.0, 0.0, 0.0);
        assert!(matches!(
            loc.on_global_fix(far, 100),
            FixOutcome::Jumped { .. }
        ));
        assert!(close(loc.estimate(), far, 1e-9));
        assert_eq!(loc.on_global_fix(far, 50), FixOutcome::Rejected, "older");
        let nan = Pose2::new(f64::NAN, 0.0, 0.0);
        assert_eq!(loc.on_global_fix(nan, 200), FixOutcome::Rejected);
    }

    #[test]
    fn table_pose_is_valid_until_the_base_moves() {
        let mut loc = Localiser::new(LocaliserConfig::default());
        loc.on_global_fix(Pose2::new(1.0, 5.0, 1.57), 1);
        let fix = Pose2::new(1.02, 5.01, 1.56);
        loc.on_table_fix(fix, 100);
        assert_eq!(loc.table_pose(50), Some(fix));
        assert_eq!(loc.table_pose(150), None, "older than asked");
        loc.on_odometry(Pose2::new(0.02, 0.0, 0.0));
        assert_eq!(loc.table_pose(50), None, "moved");
    }
}
