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

use ur5e_kin::{BasePose, Joints};
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
        /// To.
        to: (f64, f64),
    },
    /// The arm motions of an unload at a measured base pose.
    Unload {
        /// Request id.
        id: u64,
        /// Measured base pose.
        base: BasePose,
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
        prior: crate::localisation::PlanarPose,
        /// The odometry pose then.
        odom: crate::localisation::PlanarPose,
        /// Points used in `points`.
        count: u16,
        /// The scan's points, base frame (m).
        points: [[f32; 2]; ALIGN_POINTS],
    },
}

/// Most points an alignment job carries (one per bearing of the monitor's obstacles).
pub const ALIGN_POINTS: usize = motion_control::collision::BINS;

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
    Align(
        u64,
        super::scan_match::Alignment,
        crate::localisation::PlanarPose,
    ),
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
                for job in inbox {
                    let answer = match job {
                        Job::Path { id, from, to } => Answer::Path(
                            id,
                            grids
                                .iter()
                                .map(|g| plan(g, from, to))
                                .find(Result::is_ok)
                                .unwrap_or(Err(PathFailure::NoRoute)),
                        ),
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

/// Plans on the grid; if the start (where the base really stands, e.g. close to the table after
/// an unload) lies in the inflated obstacles, leaves it straight towards the goal first.
fn plan(
    grid: &OccupancyGrid,
    from: (f64, f64),
    to: (f64, f64),
) -> Result<FollowerPath, PathFailure> {
    let route = grid.plan(from, to).or_else(|| {
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
    });
    let Some(route) = route else {
        return Err(PathFailure::NoRoute);
    };
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
