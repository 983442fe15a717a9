//! Statistics of the records: difficulty thirds by servable area, means with their errors, paired differences.

use super::*;

/// Difficulty third of a task.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum Difficulty {
    /// Largest servable areas.
    Easy,
    /// Middle third.
    Normal,
    /// Smallest servable areas.
    Hard,
}

impl Difficulty {
    /// Easy, Normal, Hard.
    pub const ALL: [Difficulty; 3] = [Difficulty::Easy, Difficulty::Normal, Difficulty::Hard];
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Difficulty::Easy => "easy",
            Difficulty::Normal => "normal",
            Difficulty::Hard => "hard",
        }
    }
}

/// Servable area of a task (m^2): the expected area from which its targets can be served, i.e.
/// the ground-truth success fraction summed over both sides' candidate cells, times the cell area.
pub fn servable_area_m2(truth: &HeatmapSet, task: &EvalTask) -> f64 {
    let cell_area = CELL_SIZE_M * CELL_SIZE_M;
    truth
        .for_task(task)
        .iter()
        .map(|h| {
            candidate_cells()
                .map(|(r, c)| h.get(r, c) as f64)
                .sum::<f64>()
                * cell_area
        })
        .sum()
}

/// The paper's grouping: sort tasks by servable area and split them in thirds (smallest area =
/// hard). Returns one difficulty per task id. Ties keep task order.
pub fn difficulty_groups(areas: &[f64]) -> Vec<Difficulty> {
    let mut order: Vec<usize> = (0..areas.len()).collect();
    order.sort_by(|&a, &b| areas[a].total_cmp(&areas[b]).then(a.cmp(&b)));
    let mut out = vec![Difficulty::Normal; areas.len()];
    let n = areas.len();
    for (rank, &i) in order.iter().enumerate() {
        out[i] = if rank * 3 < n {
            Difficulty::Hard
        } else if rank * 3 < 2 * n {
            Difficulty::Normal
        } else {
            Difficulty::Easy
        };
    }
    out
}

/// Aggregate of a set of records.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stats {
    /// Tasks.
    pub tasks: usize,
    /// Fraction of objects placed (the paper's task completion rate).
    pub completion: f64,
    /// Fraction of tasks with every object placed.
    pub all_placed: f64,
    /// Mean execution time (s).
    pub mean_time_s: f64,
    /// Standard deviation of execution time over tasks (s).
    pub std_time_s: f64,
    /// Mean motion-planner calls to decide.
    pub mean_calls: f64,
}

impl Stats {
    /// Aggregates records.
    pub fn of<'a>(records: impl IntoIterator<Item = &'a TaskRecord>) -> Stats {
        let rs: Vec<&TaskRecord> = records.into_iter().collect();
        if rs.is_empty() {
            return Stats::default();
        }
        let n = rs.len() as f64;
        let objects: usize = rs.iter().map(|r| r.objects).sum();
        let placed: usize = rs.iter().map(|r| r.placed).sum();
        let mean_time_s = rs.iter().map(|r| r.time_s).sum::<f64>() / n;
        let var = rs
            .iter()
            .map(|r| (r.time_s - mean_time_s).powi(2))
            .sum::<f64>()
            / n;
        Stats {
            tasks: rs.len(),
            completion: placed as f64 / objects.max(1) as f64,
            all_placed: rs.iter().filter(|r| r.placed == r.objects).count() as f64 / n,
            mean_time_s,
            std_time_s: var.sqrt(),
            mean_calls: rs
                .iter()
                .map(|r| r.motion_planner_calls as f64)
                .sum::<f64>()
                / n,
        }
    }
}

/// The tables of an evaluation.
#[derive(Debug, Clone)]
pub struct Summary {
    /// (method, difficulty or None for all) -> stats at the main speed.
    pub main: Vec<(MethodKind, Option<Difficulty>, Stats)>,
    /// (speed, method) -> stats over all tasks.
    pub sweep: Vec<(f64, MethodKind, Stats)>,
    /// Fig. 5 points: (method, difficulty, mean time of 10 tasks, completion of those 10).
    pub points: Vec<(MethodKind, Difficulty, f64, f64)>,
    /// GROP minus each other method at the main speed, paired over the same tasks:
    /// (method, difficulty or None for all, difference).
    pub paired: Vec<(MethodKind, Option<Difficulty>, PairedDiff)>,
    /// GROP+ minus GROP at the main speed, paired over the same tasks (when both ran):
    /// (difficulty or None for all, difference).
    pub plus: Vec<(Option<Difficulty>, PlusDiff)>,
}

/// GROP+ minus GROP on the same tasks: completion, all placed, time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlusDiff {
    /// Per-task fraction placed.
    pub completion: PairedDiff,
    /// Per task 1 if every object was placed, else 0.
    pub all_placed: PairedDiff,
    /// Task time (s).
    pub time_s: PairedDiff,
}

impl PlusDiff {
    /// `a - b` over the tasks both ran.
    pub fn of(a: &[&TaskRecord], b: &[&TaskRecord]) -> PlusDiff {
        PlusDiff {
            completion: PairedDiff::of(a, b),
            all_placed: PairedDiff::of_metric(a, b, |r| f64::from(u8::from(r.placed == r.objects))),
            time_s: PairedDiff::of_metric(a, b, |r| r.time_s),
        }
    }
}

/// Mean difference of per-task completion between two methods on the same tasks, with its
/// standard error (the spread of the per-task differences over the square root of their count).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PairedDiff {
    /// Tasks paired.
    pub tasks: usize,
    /// Mean of (placed / objects) of the first method minus the second's.
    pub mean: f64,
    /// Standard error of that mean.
    pub std_error: f64,
}

impl PairedDiff {
    /// The paired difference `a - b` of per-task completion over the tasks both ran.
    pub fn of(a: &[&TaskRecord], b: &[&TaskRecord]) -> PairedDiff {
        Self::of_metric(a, b, |r| r.placed as f64 / r.objects.max(1) as f64)
    }

    /// The paired difference `a - b` of a per-task measure over the tasks both ran.
    pub fn of_metric(
        a: &[&TaskRecord],
        b: &[&TaskRecord],
        rate: impl Fn(&TaskRecord) -> f64,
    ) -> PairedDiff {
        let by_task: std::collections::HashMap<usize, f64> =
            b.iter().map(|r| (r.task, rate(r))).collect();
        let d: Vec<f64> = a
            .iter()
            .filter_map(|r| by_task.get(&r.task).map(|rb| rate(r) - rb))
            .collect();
        if d.len() < 2 {
            return PairedDiff {
                tasks: d.len(),
                mean: d.first().copied().unwrap_or(0.0),
                std_error: f64::NAN,
            };
        }
        let n = d.len() as f64;
        let mean = d.iter().sum::<f64>() / n;
        let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        PairedDiff {
            tasks: d.len(),
            mean,
            std_error: (var / n).sqrt(),
        }
    }
}
