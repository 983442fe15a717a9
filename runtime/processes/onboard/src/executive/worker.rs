//! Planning off the control thread: base paths (the navigation planner's corner visibility
//! graph / Theta* on the occupancy grid) and arm motions for an unload (IK and RRT-Connect)
//! allocate, so they run in a worker thread; the control loop sends a job and picks the answer
//! up in a later cycle through bounded channels, allocation-free.
//! Each request holds the runtime clock ([`Clock::begin_hold`]) until its answer is sent, so on
//! a simulated clock the path takes no simulated time and a run replays the same way; on the
//! robot the hold does nothing and the base simply waits a cycle or two.

use std::sync::Arc;

use grop_clock::Clock;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};

use planar::Pose2;
use ur5e_kin::Joints;
use world::nav::OccupancyGrid;
use world::{RobotConfig, Scene};

use super::unload::{UnloadFailure, UnloadPlan, plan_unload};

/// Most points of a base path the follower holds.
pub const MAX_PATH_POINTS: usize = 64;

/// A path in the follower's fixed-capacity form.
pub type FollowerPath = heapless::Vec<[f32; 2], MAX_PATH_POINTS>;

/// Why no path came back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathFailure {
    /// The grid has no free route between the two points.
    NoRoute,
    /// The worker is gone.
    WorkerGone,
}

/// A job for the worker.
#[derive(Debug, Clone, Copy)]
#[allow(clippy::large_enum_variant)]
pub enum Job {
    /// A base path between two points.
    Path {
        /// Request id.
        id: u64,
        /// From, world (m).
        from: (f64, f64),
        /// The base's heading there (rad): the path is checked from it.
        from_yaw: f64,
        /// To.
        to: (f64, f64),
        /// What the range sensor sees around the base (world frame), filled in by the shell:
        /// returns the map does not explain are planned around.
        seen: SeenPoints,
    },
    /// The arm motions of an unload at a measured base pose.
    Unload {
        /// Request id.
        id: u64,
        /// Measured base pose.
        base: Pose2,
        /// Object goal, world (m).
        target: [f64; 3],
        /// Joints over the object's tray slot (where the transit starts).
        from_slot: Joints,
        /// Carry pose (where it ends).
        carry: Joints,
        /// RRT seed.
        seed: u64,
    },
    /// Align a scan to the map (the shell's job, not the core's: the answer becomes a fix).
    Align {
        /// Request id.
        id: u64,
        /// The estimate when the scan was taken.
        prior: planar::Pose2,
        /// The odometry pose then.
        odom: planar::Pose2,
        /// Points used in `points`.
        count: u16,
        /// The scan's points, base frame (m).
        points: [[f32; 2]; ALIGN_POINTS],
    },
}

/// Most points an alignment job carries (one per bearing of the monitor's obstacles).
pub const ALIGN_POINTS: usize = motion_control::collision::BINS;

/// The range sensor's points (world frame, m) handed to a path job.
#[derive(Debug, Clone, Copy)]
pub struct SeenPoints {
    count: u16,
    points: [[f32; 2]; ALIGN_POINTS],
}

impl SeenPoints {
    /// None seen (no sensor, or not filled in).
    pub const NONE: Self = Self {
        count: 0,
        points: [[0.0; 2]; ALIGN_POINTS],
    };

    /// Adds a point; false when full.
    pub fn push(&mut self, x_m: f32, y_m: f32) -> bool {
        let Some(slot) = self.points.get_mut(usize::from(self.count)) else {
            return false;
        };
        *slot = [x_m, y_m];
        self.count += 1;
        true
    }

    /// The points held.
    pub fn as_slice(&self) -> &[[f32; 2]] {
        &self.points[..usize::from(self.count).min(ALIGN_POINTS)]
    }
}

/// A return farther than this from every map edge is not explained by the map (m): the
/// localisation error plus the sensor's noise.
pub const UNEXPLAINED_BEYOND_M: f64 = 0.15;

/// Returns farther than this from the base are not planned around (m): the scan is sparse and
/// old by the time the base gets there; the map and the next plans cover it.
pub const SEEN_RANGE_M: f64 = 4.0;

/// Margins around the footprint (m) of the heading-true checks, tried in turn: the path
/// clearance of the grids before them, then the collision monitor's stop zone plus the
/// sensor's noise.
pub const HEADING_TRUE_MARGINS_M: [f64; 3] = [0.15, 0.075, 0.04];

/// The worker's answer. Variants travel by value through the preallocated channel (boxing the
/// large one would allocate per answer), hence the size difference.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)]
pub enum Answer {
    /// To a path job.
    Path(u64, Result<FollowerPath, PathFailure>),
    /// To an unload job.
    Unload(u64, Result<UnloadPlan, UnloadFailure>),
    /// A scan alignment and the odometry it was taken at.
    Align(u64, super::scan_match::Alignment, planar::Pose2),
}

/// The worker's handle.
pub struct Worker {
    jobs: SyncSender<Job>,
    answers: Receiver<Answer>,
    clock: Arc<dyn Clock>,
}

impl std::fmt::Debug for Worker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Worker").finish_non_exhaustive()
    }
}

impl Worker {
    /// Starts the worker on the map; it ends each job's hold on `clock`. Paths are planned on
    /// the first of `grids` that has a route: the caller orders them from the widest clearance
    /// from furniture (room for the localisation error) to none (goals between chairs).
    pub fn start(
        grids: Vec<Arc<OccupancyGrid>>,
        scene: Scene,
        robot: RobotConfig,
        clock: Arc<dyn Clock>,
    ) -> std::io::Result<Self> {
        let (jobs, inbox) = sync_channel::<Job>(4);
        let (outbox, answers) = sync_channel::<Answer>(4);
        let worker_clock = Arc::clone(&clock);
        std::thread::Builder::new()
            .name("grop-planning".into())
            .spawn(move || {
                let mut obstacles = Vec::new();
                let edges = super::scan_match::MapEdges::of_scene(&scene);
                let planner = PathPlanner::new(grids, &scene, &robot);
                for job in inbox {
                    let answer = match job {
                        Job::Path {
                            id,
                            from,
                            from_yaw,
                            to,
                            seen,
                        } => {
                            let unexplained = unexplained(&edges, from, &seen);
                            Answer::Path(id, planner.plan(from, from_yaw, to, &unexplained))
                        }
                        Job::Unload {
                            id,
                            base,
                            target,
                            from_slot,
                            carry,
                            seed,
                        } => {
                            scene.obstacle_boxes_into(&robot, base, &mut obstacles);
                            let planned = plan_unload(
                                &robot.place,
                                base,
                                target,
                                &obstacles,
                                &from_slot,
                                &carry,
                                seed,
                            );
                            if let Err(e) = &planned {
                                log::info!(
                                    "unload at base ({:.3}, {:.3}, {:.3}) for target {target:?}: {e:?}",
                                    base.x_m,
                                    base.y_m,
                                    base.yaw_rad
                                );
                            }
                            Answer::Unload(id, planned)
                        }
                        Job::Align {
                            id,
                            prior,
                            odom,
                            count,
                            points,
                        } => Answer::Align(
                            id,
                            super::scan_match::align(
                                &edges,
                                &points[..usize::from(count).min(ALIGN_POINTS)],
                                prior,
                            ),
                            odom,
                        ),
                    };
                    let sent = outbox.send(answer);
                    worker_clock.end_hold();
                    if sent.is_err() {
                        return;
                    }
                }
            })?;
        Ok(Self {
            jobs,
            answers,
            clock,
        })
    }

    /// Hands a job over; false if the queue is full (try again next cycle).
    pub fn submit(&self, job: Job) -> Result<bool, PathFailure> {
        self.clock.begin_hold();
        match self.jobs.try_send(job) {
            Ok(()) => Ok(true),
            Err(e) => {
                self.clock.end_hold();
                match e {
                    TrySendError::Full(_) => Ok(false),
                    TrySendError::Disconnected(_) => Err(PathFailure::WorkerGone),
                }
            }
        }
    }

    /// An answer, if one is ready.
    pub fn try_answer(&self) -> Option<Answer> {
        self.answers.try_recv().ok()
    }
}

/// The base paths: heading-true where the map and the scan allow, the any-heading grid's
/// path as the last resort.
struct PathPlanner {
    /// The any-heading grids, widest clearance first, the bare footprint last.
    grids: Vec<Arc<OccupancyGrid>>,
    /// One lattice per [`HEADING_TRUE_MARGINS_M`].
    lattices: Vec<world::nav::lattice::Lattice>,
}

impl PathPlanner {
    fn new(grids: Vec<Arc<OccupancyGrid>>, scene: &Scene, robot: &RobotConfig) -> Self {
        let started = std::time::Instant::now();
        let lattices = HEADING_TRUE_MARGINS_M
            .iter()
            .map(|&m| world::nav::lattice::Lattice::new(scene, robot, m))
            .collect();
        log::info!(
            "heading-true lattices for margins {HEADING_TRUE_MARGINS_M:?} m built in {:.1} ms",
            started.elapsed().as_secs_f64() * 1e3
        );
        Self { grids, lattices }
    }

    /// For each margin in turn: the grid's any-angle path if the base can drive it at its real
    /// headings (facing along each stretch, turning in place at the corners, clear of the
    /// `seen` points too), else a lattice path that it can. Failing every margin, the bare
    /// grid's path as before (the collision monitor is the net), logged.
    fn plan(
        &self,
        from: (f64, f64),
        from_yaw: f64,
        to: (f64, f64),
        seen: &[(f64, f64)],
    ) -> Result<FollowerPath, PathFailure> {
        for (k, lattice) in self.lattices.iter().enumerate() {
            let lattice = if seen.is_empty() {
                std::borrow::Cow::Borrowed(lattice)
            } else {
                std::borrow::Cow::Owned(lattice.with_points(seen))
            };
            let grid = self.grids.get(k).or(self.grids.last());
            if let Some(route) = grid.and_then(|g| route_on(g, from, to))
                && lattice.drivable(from_yaw, &route.points)
            {
                return follower_path(&route);
            }
            if let Some(route) = lattice.plan(from, from_yaw, to) {
                log::info!(
                    "path ({:.2}, {:.2}) -> ({:.2}, {:.2}): heading-true lattice path, margin {:.3} m, {} seen points, {:.2} m",
                    from.0,
                    from.1,
                    to.0,
                    to.1,
                    lattice.clearance().margin_m(),
                    seen.len(),
                    route.length_m
                );
                return follower_path(&route);
            }
        }
        log::info!(
            "path ({:.2}, {:.2}) -> ({:.2}, {:.2}): no heading-true path ({} seen points); the any-heading grid's",
            from.0,
            from.1,
            to.0,
            to.1,
            seen.len()
        );
        self.grids
            .iter()
            .find_map(|g| route_on(g, from, to))
            .map_or(Err(PathFailure::NoRoute), |route| follower_path(&route))
    }
}

/// How deep behind a return the unseen part of what it hit is assumed to reach (m): a chair's
/// depth. The sensor sees the faces turned to it; planning around the face alone would route
/// through the rest.
pub const SHADOW_DEPTH_M: f64 = 0.45;

/// Spacing of the points filled in behind a return (m).
const SHADOW_STEP_M: f64 = 0.075;

/// The points of `seen` within [`SEEN_RANGE_M`] of `from` (where the sensor is) that no map
/// edge explains, each with its shadow: points behind it along the ray, [`SHADOW_DEPTH_M`]
/// deep.
fn unexplained(
    edges: &super::scan_match::MapEdges,
    from: (f64, f64),
    seen: &SeenPoints,
) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for p in seen.as_slice() {
        let (x, y) = (f64::from(p[0]), f64::from(p[1]));
        let range = (x - from.0).hypot(y - from.1);
        if !(1e-6..=SEEN_RANGE_M).contains(&range) || edges.distance_m(x, y) <= UNEXPLAINED_BEYOND_M
        {
            continue;
        }
        let (ux, uy) = ((x - from.0) / range, (y - from.1) / range);
        let steps = (SHADOW_DEPTH_M / SHADOW_STEP_M).round() as usize;
        out.extend((0..=steps).map(|k| {
            let d = k as f64 * SHADOW_STEP_M;
            (x + ux * d, y + uy * d)
        }));
    }
    out
}

/// The route on the grid; if the start (where the base really stands, e.g. close to the table
/// after an unload) lies in the inflated obstacles, leaves it straight towards the goal first.
fn route_on(grid: &OccupancyGrid, from: (f64, f64), to: (f64, f64)) -> Option<world::nav::NavPath> {
    grid.plan(from, to).or_else(|| {
        // Step out of the inflated obstacle towards the goal, up to 1 m.
        let (dx, dy) = (to.0 - from.0, to.1 - from.1);
        let d = dx.hypot(dy).max(1e-9);
        (1..=10).find_map(|k| {
            let s = 0.1 * k as f64;
            let p = (from.0 + dx / d * s, from.1 + dy / d * s);
            grid.is_free(p)
                .then(|| grid.plan(p, to))
                .flatten()
                .map(|mut path| {
                    path.points.insert(0, from);
                    path
                })
        })
    })
}

/// A route in the follower's form.
fn follower_path(route: &world::nav::NavPath) -> Result<FollowerPath, PathFailure> {
    let mut points = FollowerPath::new();
    // Keep the ends; thin the middle if a route ever has more corners than the follower holds.
    let n = route.points.len();
    let stride = n.div_ceil(MAX_PATH_POINTS - 1).max(1);
    for (i, p) in route.points.iter().enumerate() {
        if i % stride == 0 || i + 1 == n {
            let _ = points.push([p.0 as f32, p.1 as f32]);
        }
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

    use super::*;
    use world::nav::lattice::Lattice;

    fn planner(scene: &Scene, robot: &RobotConfig) -> PathPlanner {
        let grids = [0.15, 0.075, 0.0]
            .iter()
            .map(|m| {
                let mut r = robot.clone();
                r.footprint.length_m += 2.0 * m;
                r.footprint.width_m += 2.0 * m;
                Arc::new(OccupancyGrid::from_scene(scene, &r))
            })
            .collect();
        PathPlanner::new(grids, scene, robot)
    }

    fn points(path: &FollowerPath) -> Vec<(f64, f64)> {
        path.iter()
            .map(|p| (f64::from(p[0]), f64::from(p[1])))
            .collect()
    }

    #[test]
    fn a_chair_the_scan_sees_and_the_map_does_not_is_planned_around() {
        let scene = Scene::empty_paper_room();
        let robot = RobotConfig::default();
        let edges = super::super::scan_match::MapEdges::of_scene(&scene);
        let planner = planner(&scene, &robot);
        let (from, to) = ((-3.0, 2.0), (3.0, 2.0));
        let straight = planner.plan(from, 0.0, to, &[]).expect("a path");
        assert_eq!(
            straight.len(),
            2,
            "straight across the empty room: {straight:?}"
        );
        // A chair on the way, seen by the sensor as the edge facing the base, and returns on
        // the loading table's top (mapped) that must not count.
        let mut seen = SeenPoints::NONE;
        for k in 0..10 {
            let _ = seen.push(-0.225, 1.775 + 0.05 * k as f32);
        }
        for k in 0..10 {
            let _ = seen.push(-0.7 + 0.15 * k as f32, 0.6);
        }
        let chair = unexplained(&edges, from, &seen);
        let shadow = 1 + (SHADOW_DEPTH_M / SHADOW_STEP_M).round() as usize;
        assert_eq!(
            chair.len(),
            10 * shadow,
            "only the chair's returns, each with its shadow: {chair:?}"
        );
        let around = planner.plan(from, 0.0, to, &chair).expect("a way round");
        let lattice = Lattice::new(&scene, &robot, 0.04).with_points(&chair);
        assert!(lattice.drivable(0.0, &points(&around)), "{around:?}");
        assert!(
            around.len() > 2,
            "not straight through the chair: {around:?}"
        );
        // Beyond the seen range the chair is left to the collision monitor.
        let far = unexplained(&edges, (-6.0, 2.0), &seen);
        assert!(far.is_empty(), "{far:?}");
    }

    #[test]
    fn a_stretch_that_fits_only_at_another_heading_is_planned_around() {
        // Hand-made scene 03 (chairs pushed in with 0.8 m gaps): the any-heading grid's route
        // from the west side to the loading station's corner is one straight stretch that the
        // base, facing along it, cannot drive (found by a survey of random legs in the
        // hand-made scenes: 12 of 455 such routes were not drivable at their real headings).
        let scene = Scene::from_toml_str(
            include_str!("../../../../../hil-tests/layouts/03-near-row-gaps-0.8.toml"),
            "03-near-row-gaps-0.8.toml",
        )
        .expect("scene 03");
        let robot = RobotConfig::default();
        let planner = planner(&scene, &robot);
        let (from, yaw, to) = ((-7.0984, 3.67856), -0.3354, (0.2964, 0.91776));
        let path = planner.plan(from, yaw, to, &[]).expect("a path");
        let bare = Lattice::new(&scene, &robot, 0.0);
        assert!(bare.drivable(yaw, &points(&path)), "{path:?}");
        // What the grids alone give (the path before heading-true checks) is not drivable.
        let any_heading = planner
            .grids
            .iter()
            .find_map(|g| route_on(g, from, to))
            .expect("a grid route");
        assert!(!bare.drivable(yaw, &any_heading.points), "{any_heading:?}");
    }
}
