//! Base paths off the control thread: the navigation planner (corner visibility graph / Theta*
//! on the occupancy grid) allocates, so it runs in a worker thread; the control loop sends a
//! request and picks the answer up in a later cycle through bounded channels, allocation-free.
//! Each request holds the runtime clock ([`Clock::begin_hold`]) until its answer is sent, so on
//! a simulated clock the path takes no simulated time and a run replays the same way; on the
//! robot the hold does nothing and the base simply waits a cycle or two.

use std::sync::Arc;

use grop_clock::Clock;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};

use world::nav::OccupancyGrid;

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

/// Answer to request `id`.
pub type PathAnswer = (u64, Result<FollowerPath, PathFailure>);

/// A request: id, from, to.
type PathRequest = (u64, (f64, f64), (f64, f64));

/// The worker's handle.
pub struct PathWorker {
    requests: SyncSender<PathRequest>,
    answers: Receiver<PathAnswer>,
    clock: Arc<dyn Clock>,
}

impl std::fmt::Debug for PathWorker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PathWorker").finish_non_exhaustive()
    }
}

impl PathWorker {
    /// Starts the worker on `grid`; it ends each request's hold on `clock`.
    pub fn start(grid: Arc<OccupancyGrid>, clock: Arc<dyn Clock>) -> std::io::Result<Self> {
        let (requests, inbox) = sync_channel::<PathRequest>(4);
        let (outbox, answers) = sync_channel::<PathAnswer>(4);
        let worker_clock = Arc::clone(&clock);
        std::thread::Builder::new()
            .name("grop-paths".into())
            .spawn(move || {
                for (id, from, to) in inbox {
                    let answer = plan(&grid, from, to);
                    let sent = outbox.send((id, answer));
                    worker_clock.end_hold();
                    if sent.is_err() {
                        return;
                    }
                }
            })?;
        Ok(Self {
            requests,
            answers,
            clock,
        })
    }

    /// Asks for a path; false if the queue is full (ask again next cycle).
    pub fn request(&self, id: u64, from: (f64, f64), to: (f64, f64)) -> Result<bool, PathFailure> {
        self.clock.begin_hold();
        match self.requests.try_send((id, from, to)) {
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
    pub fn try_answer(&self) -> Option<PathAnswer> {
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
