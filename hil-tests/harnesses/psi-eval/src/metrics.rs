//! Quality of a predicted heatmap against a ground-truth heatmap, over the labelled (candidate)
//! cells only: cell-level MAE, Brier score and calibration (ECE), task-level feasibility error
//! |F_hat - F| (paper eq. 4) and the expected success of the navigation goal Smp draws.

use serde::{Deserialize, Serialize};
use world::Heatmap;
use world::view::{CROP_COLS, candidate_cells};

/// Bins of the expected calibration error (equal width over [0, 1]).
pub const ECE_BINS: usize = 10;

/// Task-level feasibility of one location in closed form (paper eq. 4): the expected heatmap
/// value at a cell drawn by Smp (probability proportional to the value), sum(v^2) / sum(v) over
/// the candidate cells; 0 when the heatmap is 0 everywhere (nothing to draw, nothing feasible).
pub fn task_feasibility(heat: &Heatmap) -> f64 {
    let (mut s1, mut s2) = (0.0f64, 0.0f64);
    for (r, c) in candidate_cells() {
        let v = f64::from(heat.values()[r * CROP_COLS + c]).max(0.0);
        s1 += v;
        s2 += v * v;
    }
    if s1 > 0.0 { s2 / s1 } else { 0.0 }
}

/// True success probability of the goal Smp draws from `predicted` (paper Alg. 1 line 10):
/// sum(p * y) / sum(p) over candidate cells, where y is the true success fraction; 0 when the
/// prediction is 0 everywhere (the planner has no goal to send the robot to).
pub fn smp_expected_success(predicted: &Heatmap, truth: &Heatmap) -> f64 {
    let (mut sp, mut spy) = (0.0f64, 0.0f64);
    for (r, c) in candidate_cells() {
        let i = r * CROP_COLS + c;
        let p = f64::from(predicted.values()[i]).max(0.0);
        sp += p;
        spy += p * f64::from(truth.values()[i]);
    }
    if sp > 0.0 { spy / sp } else { 0.0 }
}

/// As [`smp_expected_success`], with Smp drawing only among the cells where `free` is positive
/// (the obstacle-free cells, as GROP draws by default: `PlannerConfig::free_goals_only`).
pub fn smp_expected_success_free(predicted: &Heatmap, truth: &Heatmap, free: &Heatmap) -> f64 {
    let mut masked = predicted.clone();
    for (v, f) in masked.values_mut().iter_mut().zip(free.values()) {
        if *f <= 0.0 {
            *v = 0.0;
        }
    }
    smp_expected_success(&masked, truth)
}

/// True success probability of a goal at the prediction's best cell (the "best-of-n goals"
/// limit of Smp): mean true success fraction over the candidate cells that reach the predicted
/// maximum (ties averaged, so a flat binary map is not credited for a lucky first cell); 0 when
/// the prediction is 0 everywhere.
pub fn argmax_success(predicted: &Heatmap, truth: &Heatmap) -> f64 {
    let max = candidate_cells()
        .map(|(r, c)| predicted.values()[r * CROP_COLS + c])
        .fold(0.0f32, f32::max);
    if max <= 0.0 {
        return 0.0;
    }
    let (mut n, mut sum) = (0u32, 0.0f64);
    for (r, c) in candidate_cells() {
        let i = r * CROP_COLS + c;
        if predicted.values()[i] == max {
            n += 1;
            sum += f64::from(truth.values()[i]);
        }
    }
    sum / f64::from(n)
}

/// Running sums over many (prediction, truth) pairs; [`MetricsAccumulator::report`] gives the
/// averages.
#[derive(Clone, Debug, Default)]
pub struct MetricsAccumulator {
    cells: u64,
    abs_err: f64,
    brier: f64,
    bin_count: [u64; ECE_BINS],
    bin_pred: [f64; ECE_BINS],
    bin_true: [f64; ECE_BINS],
    tasks: u64,
    f_abs_err: f64,
    f_pred: f64,
    f_true: f64,
    smp_success: f64,
    smp_success_free: f64,
    smp_success_free_true: f64,
    argmax_success: f64,
    argmax_success_true: f64,
}

impl MetricsAccumulator {
    /// Adds one task's heatmaps (prediction and ground truth, same layout) and which candidate
    /// cells are obstacle-free (`free` > 0; `None`: all of them).
    pub fn add(&mut self, predicted: &Heatmap, truth: &Heatmap, free: Option<&Heatmap>) {
        for (r, c) in candidate_cells() {
            let i = r * CROP_COLS + c;
            let p = f64::from(predicted.values()[i]).clamp(0.0, 1.0);
            let y = f64::from(truth.values()[i]);
            self.cells += 1;
            self.abs_err += (p - y).abs();
            // Brier score on the individual trials behind y: mean over trials of (p - o)^2 with
            // a fraction y of outcomes 1, = (p - y)^2 + y (1 - y).
            self.brier += (p - y) * (p - y) + y * (1.0 - y);
            let bin = ((p * ECE_BINS as f64) as usize).min(ECE_BINS - 1);
            self.bin_count[bin] += 1;
            self.bin_pred[bin] += p;
            self.bin_true[bin] += y;
        }
        let f_pred = task_feasibility(predicted);
        let f_true = task_feasibility(truth);
        self.tasks += 1;
        self.f_abs_err += (f_pred - f_true).abs();
        self.f_pred += f_pred;
        self.f_true += f_true;
        self.smp_success += smp_expected_success(predicted, truth);
        let all_free = Heatmap::from_values([1.0; world::view::CROP_CELLS]);
        let free = free.unwrap_or(&all_free);
        self.smp_success_free += smp_expected_success_free(predicted, truth, free);
        self.smp_success_free_true += smp_expected_success_free(truth, truth, free);
        self.argmax_success += argmax_success(predicted, truth);
        self.argmax_success_true += argmax_success(truth, truth);
    }

    /// Averages so far (all zero before the first task).
    pub fn report(&self, evaluator: &str) -> QualityReport {
        let n = self.cells.max(1) as f64;
        let t = self.tasks.max(1) as f64;
        let ece = (0..ECE_BINS)
            .filter(|&b| self.bin_count[b] > 0)
            .map(|b| (self.bin_pred[b] - self.bin_true[b]).abs() / n)
            .sum();
        QualityReport {
            evaluator: evaluator.to_owned(),
            tasks: self.tasks,
            cells: self.cells,
            mae: self.abs_err / n,
            brier: self.brier / n,
            ece,
            f_abs_err: self.f_abs_err / t,
            f_mean_pred: self.f_pred / t,
            f_mean_true: self.f_true / t,
            smp_success: self.smp_success / t,
            smp_success_true: self.f_true / t,
            smp_success_free: self.smp_success_free / t,
            smp_success_free_true: self.smp_success_free_true / t,
            argmax_success: self.argmax_success / t,
            argmax_success_true: self.argmax_success_true / t,
        }
    }
}

/// Averages over the tasks and labelled cells of an evaluation set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct QualityReport {
    /// Which evaluator.
    pub evaluator: String,
    /// (target, side) pairs evaluated.
    pub tasks: u64,
    /// Labelled cells evaluated (tasks x 192).
    pub cells: u64,
    /// Mean |p - y| over cells (y = true success fraction).
    pub mae: f64,
    /// Brier score over the individual trials, (p - y)^2 + y (1 - y) averaged over cells; its
    /// floor, reached by a perfect predictor, is the mean of y (1 - y).
    pub brier: f64,
    /// Expected calibration error, 10 equal-width bins of p, weighted by cells.
    pub ece: f64,
    /// Mean over tasks of |F(p) - F(y)| with F of paper eq. 4 (closed form).
    pub f_abs_err: f64,
    /// Mean F(p).
    pub f_mean_pred: f64,
    /// Mean F(y).
    pub f_mean_true: f64,
    /// Mean true success probability of the goal Smp draws from the prediction.
    pub smp_success: f64,
    /// The same for goals drawn from the true heatmap (= mean F(y)). Not an upper bound for
    /// other heatmaps: drawing in proportion to the value also sends the robot to marginal cells,
    /// which a map that is 1 only on a safe core avoids.
    pub smp_success_true: f64,
    /// Mean true success probability of the goal Smp draws from the prediction among the
    /// obstacle-free cells only (GROP's default draw).
    pub smp_success_free: f64,
    /// The same for the true heatmap.
    pub smp_success_free_true: f64,
    /// Mean true success of the goal at the prediction's maximum (ties averaged).
    pub argmax_success: f64,
    /// The same at the true heatmap's maximum (sampling noise of the truth makes it optimistic).
    pub argmax_success_true: f64,
}

impl QualityReport {
    /// One markdown table row (see [`QualityReport::markdown_header`]).
    pub fn markdown_row(&self) -> String {
        format!(
            "| {} | {:.4} | {:.4} | {:.4} | {:.4} | {:.3} | {:.3} | {:.3} | {:.3} |",
            self.evaluator,
            self.mae,
            self.brier,
            self.ece,
            self.f_abs_err,
            self.f_mean_pred,
            self.smp_success,
            self.smp_success_free,
            self.argmax_success
        )
    }

    /// Header of [`QualityReport::markdown_row`].
    pub fn markdown_header() -> &'static str {
        "| evaluator | MAE | Brier | ECE | \\|F_hat - F\\| | mean F_hat | success of Smp goal | of Smp goal, free cells | success of argmax goal |\n|---|---|---|---|---|---|---|---|---|"
    }

    /// The row the true heatmaps themselves would get on the task-level columns.
    pub fn markdown_truth_row(&self) -> String {
        format!(
            "| (true heatmap) | - | - | - | - | {:.3} | {:.3} | {:.3} | {:.3} |",
            self.f_mean_true,
            self.smp_success_true,
            self.smp_success_free_true,
            self.argmax_success_true
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use world::view::{CANDIDATE_COLS, CANDIDATE_ROWS};

    fn uniform(v: f32) -> Heatmap {
        let mut h = Heatmap::zeros();
        for (r, c) in candidate_cells() {
            h.set(r, c, v);
        }
        h
    }

    #[test]
    fn perfect_prediction_has_zero_error_and_brier_floor() {
        let mut truth = Heatmap::zeros();
        for (k, (r, c)) in candidate_cells().enumerate() {
            truth.set(r, c, (k % 5) as f32 / 4.0);
        }
        let mut acc = MetricsAccumulator::default();
        acc.add(&truth, &truth, None);
        let rep = acc.report("truth");
        assert_eq!(rep.cells, 192);
        assert!(rep.mae < 1e-12 && rep.ece < 1e-12 && rep.f_abs_err < 1e-12);
        let floor: f64 = candidate_cells()
            .map(|(r, c)| {
                let y = f64::from(truth.get(r, c));
                y * (1.0 - y)
            })
            .sum::<f64>()
            / 192.0;
        assert!((rep.brier - floor).abs() < 1e-12);
        assert!((rep.smp_success - rep.smp_success_true).abs() < 1e-12);
    }

    #[test]
    fn constant_prediction_numbers_by_hand() {
        // Truth: half the cells 1, half 0. Prediction: 0.5 everywhere.
        let mut truth = Heatmap::zeros();
        for (k, (r, c)) in candidate_cells().enumerate() {
            truth.set(r, c, (k % 2) as f32);
        }
        let mut acc = MetricsAccumulator::default();
        acc.add(&uniform(0.5), &truth, None);
        let rep = acc.report("half");
        assert!((rep.mae - 0.5).abs() < 1e-12);
        assert!((rep.brier - 0.25).abs() < 1e-12);
        // One bin, mean p 0.5, mean y 0.5: calibrated.
        assert!(rep.ece.abs() < 1e-12);
        // F(p) = 0.5, F(y) = 1 (Smp on the truth only draws 1-cells).
        assert!((rep.f_mean_pred - 0.5).abs() < 1e-12 && (rep.f_mean_true - 1.0).abs() < 1e-12);
        assert!((rep.f_abs_err - 0.5).abs() < 1e-12);
        // A uniform draw succeeds half the time.
        assert!((rep.smp_success - 0.5).abs() < 1e-12);
    }

    #[test]
    fn overconfident_prediction_is_miscalibrated() {
        let mut acc = MetricsAccumulator::default();
        acc.add(&uniform(0.95), &uniform(0.5), None);
        let rep = acc.report("over");
        assert!((rep.ece - 0.45).abs() < 1e-6, "{}", rep.ece);
    }

    #[test]
    fn cells_outside_the_candidate_area_do_not_count() {
        let mut pred = uniform(0.3);
        pred.set(0, 0, 1.0);
        pred.set(*CANDIDATE_ROWS.end() + 1, *CANDIDATE_COLS.start(), 1.0);
        let mut acc = MetricsAccumulator::default();
        acc.add(&pred, &uniform(0.3), None);
        assert!(acc.report("x").mae < 1e-7);
    }

    #[test]
    fn empty_heatmaps_give_zero_feasibility() {
        assert_eq!(task_feasibility(&Heatmap::zeros()), 0.0);
        assert_eq!(smp_expected_success(&Heatmap::zeros(), &uniform(1.0)), 0.0);
    }

    #[test]
    fn smp_success_weights_by_prediction() {
        // Prediction puts all mass on the one true 1-cell.
        let mut truth = Heatmap::zeros();
        truth.set(10, 30, 1.0);
        let mut pred = Heatmap::zeros();
        pred.set(10, 30, 0.2);
        assert!((smp_expected_success(&pred, &truth) - 1.0).abs() < 1e-12);
        pred.set(10, 31, 0.2);
        assert!((smp_expected_success(&pred, &truth) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn smp_success_free_draws_among_free_cells_only() {
        let mut truth = Heatmap::zeros();
        truth.set(10, 30, 1.0);
        let mut pred = Heatmap::zeros();
        pred.set(10, 30, 0.2);
        pred.set(10, 31, 0.6);
        let mut free = Heatmap::zeros();
        free.set(10, 30, 1.0);
        assert!((smp_expected_success(&pred, &truth) - 0.25).abs() < 1e-6);
        assert!((smp_expected_success_free(&pred, &truth, &free) - 1.0).abs() < 1e-12);
        // No prediction on a free cell: no goal.
        assert_eq!(
            smp_expected_success_free(&pred, &truth, &Heatmap::zeros()),
            0.0
        );
        let mut acc = MetricsAccumulator::default();
        acc.add(&pred, &truth, Some(&free));
        let r = acc.report("x");
        assert!((r.smp_success - 0.25).abs() < 1e-6);
        assert!((r.smp_success_free - 1.0).abs() < 1e-12);
        assert!((r.smp_success_free_true - 1.0).abs() < 1e-12);
    }
}
