//! Base paths off the control thread: the navigation planner (corner visibility graph / Theta*
//! on the occupancy grid) allocates, so it runs in a worker thread; the control loop sends a
//! request and picks the answer up in a later cycle through bounded channels, allocation-free.

use std::sync::Arc;
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

/// The worker's handle.
#[derive(Debug)]
pub struct PathWorker {
    requests: SyncSender<(u64, (f64, f64), (f64, f64))>,
    answers: Receiver<PathAnswer>,
}

impl PathWorker {
    /// Starts the worker on `grid`.
    pub fn start(grid: Arc<OccupancyGrid>) -> std::io::Result<Self> {
        let (requests, inbox) = sync_channel::<(u64, (f64, f64), (f64, f64))>(4);
        let (outbox, answers) = sync_channel::<PathAnswer>(4);
        std::thread::Builder::new()
            .name("grop-paths".into())
            .spawn(move || {
                for (id, from, to) in inbox {
                    let answer = plan(&grid, from, to);
                    if outbox.send((id, answer)).is_err() {
                        return;
                    }
                }
            })?;
        Ok(Self { requests, answers })
    }

    /// Asks for a path; false if the queue is full (ask again next cycle).
    pub fn request(&self, id: u64, from: (f64, f64), to: (f64, f64)) -> Result<bool, PathFailure> {
        match self.requests.try_send((id, from, to)) {
            Ok(()) => Ok(true),
            Err(TrySendError::Full(_)) => Ok(false),
            Err(TrySendError::Disconnected(_)) => Err(PathFailure::WorkerGone),
        }
    }

    /// An answer, if one is ready.
    pub fn try_answer(&self) -> Option<PathAnswer> {
        self.answers.try_recv().ok()
    }
}

/// Plans on the grid; if the start (where the base really stands, e.g. close to the table after
/// an unload) lies in the inflated obstacles, leaves it straight towards the goal first.
fn plan(grid: &OccupancyGrid, from: (f64, f64), to: (f64, f64)) -> Result<FollowerPath, PathFailure> {
    let route = grid.plan(from, to).or_else(|| {
        // Step out of the inflated obstacle towards the goal, up to 1 m.
        let (dx, dy) = (to.0 - from.0, to.1 - from.1);
        let d = dx.hypot(dy).max(1e-9);
        (1..=10).find_map(|k| {
            let s = 0.1 * k as f64;
            let p = (from.0 + dx / d * s, from.1 + dy / d * s);
            grid.is_free(p).then(|| grid.plan(p, to)).flatten().map(|mut path| {
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
