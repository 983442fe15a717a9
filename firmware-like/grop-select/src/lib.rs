//! GROP selection core: the arithmetic of the paper's decision step, `#![no_std]` and without heap,
//! so that it is deterministic and could run on a microcontroller.
//!
//! It knows nothing of scenes, images or task plans. It gets numbers and returns numbers:
//!
//! - [`task_feasibility`]: task-level feasibility `Fea^t` of one (navigate, unload) pair from the
//!   heatmap values of the location's cells, in closed form: `F = sum(v^2) / sum(v)`. This is the
//!   expectation of paper eq. 4 (the mean heatmap value at `N` draws of `Smp`) as `N -> inf`.
//! - [`smp_index`]: `Smp(l, h)` (Algorithm 1, line 10): draw one cell with probability proportional
//!   to its heatmap value. The caller owns the random number generator and passes a uniform
//!   `u in [0, 1)`, so this crate stays free of RNG state and every draw is replayable.
//! - [`plan_feasibility`]: `F(p)` of a whole plan from its pairs' `Fea^t`: the sum (Algorithm 1,
//!   line 9, the default; the expected number of objects placed) or the product (the probability
//!   that every unload succeeds).
//! - [`utility`]: `U = R * F - C` (eq. 1).
//! - [`select`] / [`Argmax`]: the argmax over candidates with the documented deterministic
//!   tie-break, returning a [`Decision`] that explains itself (F, C and U for every candidate).
//!
//! ```
//! use grop_select::{select, task_feasibility, Candidate, Decision};
//!
//! // Two candidate plans: a short risky one and a longer safe one (R = 40).
//! let risky = Candidate { feasibility: task_feasibility(&[0.1, 0.2, 0.0]), cost_s: 10.0 };
//! let safe = Candidate { feasibility: task_feasibility(&[0.9, 0.8, 0.9]), cost_s: 20.0 };
//! let decision: Decision<8> = select(40.0, &[risky, safe]).unwrap();
//! assert_eq!(decision.chosen, 1);
//! assert!(decision.scored[1].utility > decision.scored[0].utility);
//! ```
#![no_std]
#![forbid(unsafe_code)]

/// Two utilities closer than this (in seconds-equivalent units of U) count as a tie.
///
/// Plans that differ only in the order of equivalent legs have utilities that agree up to
/// floating-point summation order; treating them as ties lets the documented tie-break decide
/// instead of rounding noise.
pub const UTILITY_TIE_EPS: f64 = 1e-9;

/// Heatmap value as this crate reads it: negative and NaN values count as 0 (an FCN may output
/// slightly negative values; a NaN must never win a draw).
#[inline]
fn clean(v: f32) -> f64 {
    if v > 0.0 { v as f64 } else { 0.0 }
}

/// Task-level feasibility `Fea^t` of one (navigate, unload) pair, paper eq. 4 in closed form.
///
/// Eq. 4 averages the heatmap value `h[x]` at `N` positions drawn by `Smp`, which draws cell `i`
/// with probability `v_i / sum(v)`. Its expectation is `sum_i (v_i / sum v) * v_i =
/// sum(v^2) / sum(v)`, which is what this returns. `values` are the heatmap values of the cells of
/// the location (the candidate area); negative and NaN values count as 0. Returns 0 when every
/// value is 0 (nowhere to stand, so the pair cannot succeed). The result lies in `[0, max(v)]`.
pub fn task_feasibility(values: &[f32]) -> f64 {
    let mut sum_v = 0.0_f64;
    let mut sum_v2 = 0.0_f64;
    for &v in values {
        let v = clean(v);
        sum_v += v;
        sum_v2 += v * v;
    }
    if sum_v > 0.0 { sum_v2 / sum_v } else { 0.0 }
}

/// `Smp(l, h)`: index of the cell drawn with probability proportional to its heatmap value.
///
/// `u` must be a uniform draw in `[0, 1)` supplied by the caller; values outside are clamped into
/// that range. Negative and NaN values count as 0 and are never drawn. Returns `None` when no cell
/// has a positive value (the caller then falls back, e.g. to a uniform choice).
///
/// The draw is an inverse-CDF lookup: the first index whose cumulative value exceeds
/// `u * sum(v)`. Rounding can leave the threshold at the very end of the sum; then the last cell
/// with a positive value is returned, so a zero cell is never returned.
pub fn smp_index(values: &[f32], u: f64) -> Option<usize> {
    let total: f64 = values.iter().map(|&v| clean(v)).sum();
    if total <= 0.0 {
        return None;
    }
    let u = if u.is_nan() { 0.0 } else { u.clamp(0.0, 1.0) };
    let threshold = u * total;
    let mut cumulative = 0.0_f64;
    let mut last_positive = None;
    for (i, &v) in values.iter().enumerate() {
        let v = clean(v);
        if v <= 0.0 {
            continue;
        }
        cumulative += v;
        last_positive = Some(i);
        if cumulative > threshold {
            return Some(i);
        }
    }
    last_positive
}

/// Index of the best of several `Smp` draws (the authors' best-of-n goal option; n = 1 is the
/// paper's default): draws `Smp` once per `u` and keeps the cell with the highest heatmap value;
/// among equal values the earliest draw wins. `None` when no cell has a positive value.
pub fn smp_best_of(values: &[f32], uniforms: &[f64]) -> Option<usize> {
    let mut best: Option<usize> = None;
    for &u in uniforms {
        let i = smp_index(values, u)?;
        match best {
            Some(b) if clean(values[b]) >= clean(values[i]) => {}
            _ => best = Some(i),
        }
    }
    best
}

/// How the pairs' task-level feasibilities combine into the plan feasibility `F(p)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FeasibilityAggregation {
    /// `F(p) = sum_i Fea^t_i` (Algorithm 1, line 9): the expected number of objects placed. The
    /// paper's rule and our default.
    #[default]
    Sum,
    /// `F(p) = prod_i Fea^t_i`: the probability that every unload succeeds (independent pairs).
    Product,
}

/// Plan feasibility `F(p)` from the task-level feasibilities of its (navigate, unload) pairs.
/// An empty plan has `F = 0` under `Sum` and `F = 1` under `Product` (the empty product).
pub fn plan_feasibility(aggregation: FeasibilityAggregation, pair_feasibilities: &[f64]) -> f64 {
    match aggregation {
        FeasibilityAggregation::Sum => pair_feasibilities.iter().sum(),
        FeasibilityAggregation::Product => pair_feasibilities.iter().product(),
    }
}

/// Utility of a plan, paper eq. 1: `U = R * F - C`, with `R` the success bonus (40 in the paper),
/// `F` the plan feasibility and `C` the plan cost in seconds of travel.
#[inline]
pub fn utility(success_bonus_r: f64, feasibility: f64, cost_s: f64) -> f64 {
    success_bonus_r * feasibility - cost_s
}

/// One candidate plan as the selection step sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Plan feasibility `F(p)` (already aggregated over the plan's pairs).
    pub feasibility: f64,
    /// Plan cost `C(p)` in seconds.
    pub cost_s: f64,
}

/// A candidate with its utility: one row of a decision's explanation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scored {
    /// The candidate's index in the input.
    pub index: usize,
    /// `F(p)`.
    pub feasibility: f64,
    /// `C(p)` in seconds.
    pub cost_s: f64,
    /// `U(p) = R * F(p) - C(p)` (eq. 1).
    pub utility: f64,
}

/// Why the selection step could not decide.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SelectError {
    /// No candidates were given.
    NoCandidates,
    /// More candidates than the decision's capacity `N`; the value is that capacity.
    TooManyCandidates(usize),
    /// Candidate `index` has a NaN or infinite feasibility or cost (or `R` is not finite, then
    /// the index is 0).
    NotFinite(usize),
}

impl core::fmt::Display for SelectError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SelectError::NoCandidates => write!(f, "no candidate plans to select from"),
            SelectError::TooManyCandidates(n) => {
                write!(f, "more candidate plans than the decision holds ({n})")
            }
            SelectError::NotFinite(i) => {
                write!(
                    f,
                    "candidate {i} has a non-finite feasibility, cost or bonus"
                )
            }
        }
    }
}

impl core::error::Error for SelectError {}

/// Is `challenger` strictly better than `incumbent` under the documented rule?
///
/// Rule (deterministic, independent of platform and summation order beyond 1e-9):
/// 1. higher utility `U` wins, where utilities within [`UTILITY_TIE_EPS`] are a tie;
/// 2. on a tie, the lower cost `C` wins (same utility for less travel: the faster plan);
/// 3. on equal costs as well, the lower index wins (the candidate offered first).
///
/// Rule 3 is implemented by never replacing the incumbent on a full tie, since candidates are
/// offered in index order.
#[inline]
fn better(challenger: &Scored, incumbent: &Scored) -> bool {
    let du = challenger.utility - incumbent.utility;
    if du > UTILITY_TIE_EPS {
        return true;
    }
    if du < -UTILITY_TIE_EPS {
        return false;
    }
    challenger.cost_s < incumbent.cost_s
}

/// Streaming argmax for candidate sets too large to keep: offer candidates in index order, read
/// the best at the end. Same rule as [`select`].
#[derive(Debug, Clone, Copy)]
pub struct Argmax {
    success_bonus_r: f64,
    best: Option<Scored>,
    offered: usize,
}

impl Argmax {
    /// A fresh argmax for success bonus `R`.
    pub const fn new(success_bonus_r: f64) -> Self {
        Self {
            success_bonus_r,
            best: None,
            offered: 0,
        }
    }

    /// Offers the next candidate (its index is the number offered before it). Returns its scored
    /// row. Non-finite candidates are rejected with [`SelectError::NotFinite`] and not counted.
    pub fn offer(&mut self, candidate: Candidate) -> Result<Scored, SelectError> {
        let index = self.offered;
        if !candidate.feasibility.is_finite()
            || !candidate.cost_s.is_finite()
            || !self.success_bonus_r.is_finite()
        {
            return Err(SelectError::NotFinite(index));
        }
        let scored = Scored {
            index,
            feasibility: candidate.feasibility,
            cost_s: candidate.cost_s,
            utility: utility(
                self.success_bonus_r,
                candidate.feasibility,
                candidate.cost_s,
            ),
        };
        self.offered += 1;
        match &self.best {
            Some(b) if !better(&scored, b) => {}
            _ => self.best = Some(scored),
        }
        Ok(scored)
    }

    /// The best candidate so far, `None` before the first offer.
    pub fn best(&self) -> Option<Scored> {
        self.best
    }

    /// How many candidates were offered.
    pub fn offered(&self) -> usize {
        self.offered
    }
}

/// The outcome of a selection, explaining itself: every candidate's F, C and U, and the chosen one.
#[derive(Debug, Clone)]
pub struct Decision<const N: usize> {
    /// Index of the chosen candidate (the argmax of `U` under the tie-break rule of [`Argmax`]).
    pub chosen: usize,
    /// The success bonus `R` that was used.
    pub success_bonus_r: f64,
    /// Every candidate, in input order, with its utility.
    pub scored: heapless::Vec<Scored, N>,
}

impl<const N: usize> Decision<N> {
    /// The chosen candidate's row.
    pub fn chosen_row(&self) -> &Scored {
        // `chosen` always indexes `scored`: `select` only builds decisions from offered rows.
        &self.scored[self.chosen]
    }

    /// Margin by which the chosen candidate's utility beats the runner-up (0 on a tie, `None`
    /// with a single candidate): how close the decision was.
    pub fn margin(&self) -> Option<f64> {
        let best = self.chosen_row().utility;
        self.scored
            .iter()
            .filter(|s| s.index != self.chosen)
            .map(|s| best - s.utility)
            .reduce(f64::min)
    }
}

/// Selects the candidate of highest utility `U = R * F - C` (eq. 1; Algorithm 1, line 23) and
/// explains the decision. Tie-break: see [`Argmax`] (higher U, then lower C, then lower index).
pub fn select<const N: usize>(
    success_bonus_r: f64,
    candidates: &[Candidate],
) -> Result<Decision<N>, SelectError> {
    if candidates.is_empty() {
        return Err(SelectError::NoCandidates);
    }
    if candidates.len() > N {
        return Err(SelectError::TooManyCandidates(N));
    }
    let mut argmax = Argmax::new(success_bonus_r);
    let mut scored = heapless::Vec::new();
    for &c in candidates {
        let row = argmax.offer(c)?;
        // Capacity was checked above.
        scored
            .push(row)
            .map_err(|_| SelectError::TooManyCandidates(N))?;
    }
    let chosen = argmax
        .best()
        .map(|b| b.index)
        .ok_or(SelectError::NoCandidates)?;
    Ok(Decision {
        chosen,
        success_bonus_r,
        scored,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_feasibility_matches_hand_computation() {
        // (0.5^2 + 1^2) / (0.5 + 1) = 1.25 / 1.5
        let f = task_feasibility(&[0.5, 1.0, 0.0]);
        assert!((f - 1.25 / 1.5).abs() < 1e-12);
        assert_eq!(task_feasibility(&[0.0; 4]), 0.0);
        assert_eq!(task_feasibility(&[]), 0.0);
        // Uniform heatmap: F equals the common value.
        assert!((task_feasibility(&[0.3; 10]) - 0.3).abs() < 1e-7);
    }

    #[test]
    fn negative_and_nan_values_count_as_zero() {
        let f = task_feasibility(&[f32::NAN, -1.0, 0.5]);
        assert!((f - 0.5).abs() < 1e-12);
        for k in 0..100 {
            let u = k as f64 / 100.0;
            assert_eq!(smp_index(&[f32::NAN, -1.0, 0.5, 0.0], u), Some(2));
        }
        assert_eq!(smp_index(&[f32::NAN, -1.0, 0.0], 0.3), None);
    }

    #[test]
    fn smp_inverse_cdf_boundaries() {
        let v = [0.0, 1.0, 0.0, 3.0, 0.0];
        assert_eq!(smp_index(&v, 0.0), Some(1));
        assert_eq!(smp_index(&v, 0.2499), Some(1));
        assert_eq!(smp_index(&v, 0.25), Some(3));
        assert_eq!(smp_index(&v, 0.999_999), Some(3));
        // Out-of-range u is clamped; u = 1 lands on the last positive cell, never a zero one.
        assert_eq!(smp_index(&v, 1.0), Some(3));
        assert_eq!(smp_index(&v, 7.0), Some(3));
        assert_eq!(smp_index(&v, -2.0), Some(1));
        assert_eq!(smp_index(&v, f64::NAN), Some(1));
    }

    #[test]
    fn best_of_n_keeps_highest_value_and_first_on_ties() {
        let v = [0.2, 0.0, 0.8];
        // u = 0.1 draws cell 0, u = 0.5 draws cell 2.
        assert_eq!(smp_best_of(&v, &[0.1, 0.5]), Some(2));
        assert_eq!(smp_best_of(&v, &[0.1]), Some(0));
        assert_eq!(smp_best_of(&v, &[]), None);
        assert_eq!(smp_best_of(&[0.0, 0.0], &[0.5]), None);
    }

    #[test]
    fn utility_and_aggregation() {
        assert_eq!(utility(40.0, 0.5, 12.0), 8.0);
        assert_eq!(
            plan_feasibility(FeasibilityAggregation::Sum, &[0.5, 0.25]),
            0.75
        );
        assert_eq!(
            plan_feasibility(FeasibilityAggregation::Product, &[0.5, 0.25]),
            0.125
        );
        assert_eq!(plan_feasibility(FeasibilityAggregation::Product, &[]), 1.0);
        assert_eq!(
            FeasibilityAggregation::default(),
            FeasibilityAggregation::Sum
        );
    }

    #[test]
    fn tie_break_prefers_lower_cost_then_lower_index() {
        // All three have U = 10; candidate 1 and 2 are cheaper than 0, 1 comes first.
        let c = [
            Candidate {
                feasibility: 1.0,
                cost_s: 30.0,
            },
            Candidate {
                feasibility: 0.75,
                cost_s: 20.0,
            },
            Candidate {
                feasibility: 0.75,
                cost_s: 20.0,
            },
        ];
        let d: Decision<4> = select(40.0, &c).unwrap();
        assert_eq!(d.chosen, 1);
        assert_eq!(d.margin(), Some(0.0));
        // Below the tie tolerance the cost rule still decides.
        let c = [
            Candidate {
                feasibility: 1.0,
                cost_s: 30.0,
            },
            Candidate {
                feasibility: 0.75,
                cost_s: 20.0 + 1e-12,
            },
        ];
        let d: Decision<4> = select(40.0, &c).unwrap();
        assert_eq!(d.chosen, 1);
        // A real utility difference wins over a lower cost.
        let c = [
            Candidate {
                feasibility: 1.0,
                cost_s: 29.0,
            },
            Candidate {
                feasibility: 0.75,
                cost_s: 20.0,
            },
        ];
        let d: Decision<4> = select(40.0, &c).unwrap();
        assert_eq!(d.chosen, 0);
        assert_eq!(d.margin(), Some(1.0));
    }

    #[test]
    fn decision_explains_every_candidate() {
        let c = [
            Candidate {
                feasibility: 0.2,
                cost_s: 5.0,
            },
            Candidate {
                feasibility: 0.9,
                cost_s: 30.0,
            },
            Candidate {
                feasibility: 0.8,
                cost_s: 10.0,
            },
        ];
        let d: Decision<3> = select(40.0, &c).unwrap();
        assert_eq!(d.scored.len(), 3);
        for (i, (row, cand)) in d.scored.iter().zip(c.iter()).enumerate() {
            assert_eq!(row.index, i);
            assert_eq!(row.feasibility, cand.feasibility);
            assert_eq!(row.cost_s, cand.cost_s);
            assert_eq!(row.utility, 40.0 * cand.feasibility - cand.cost_s);
        }
        assert_eq!(d.chosen, 2);
        assert_eq!(d.chosen_row().utility, 22.0);
        assert_eq!(d.success_bonus_r, 40.0);
    }

    #[test]
    fn errors() {
        assert_eq!(
            select::<4>(40.0, &[]).unwrap_err(),
            SelectError::NoCandidates
        );
        let c = [Candidate {
            feasibility: 0.0,
            cost_s: 0.0,
        }; 5];
        assert_eq!(
            select::<4>(40.0, &c).unwrap_err(),
            SelectError::TooManyCandidates(4)
        );
        let c = [
            Candidate {
                feasibility: 0.0,
                cost_s: 0.0,
            },
            Candidate {
                feasibility: f64::NAN,
                cost_s: 0.0,
            },
        ];
        assert_eq!(
            select::<4>(40.0, &c).unwrap_err(),
            SelectError::NotFinite(1)
        );
        let c = [Candidate {
            feasibility: 0.0,
            cost_s: f64::INFINITY,
        }];
        assert_eq!(
            select::<4>(40.0, &c).unwrap_err(),
            SelectError::NotFinite(0)
        );
        assert_eq!(
            select::<4>(f64::NAN, &c[..0]).unwrap_err(),
            SelectError::NoCandidates
        );
    }

    #[test]
    fn streaming_argmax_matches_select() {
        let c = [
            Candidate {
                feasibility: 0.4,
                cost_s: 3.0,
            },
            Candidate {
                feasibility: 0.6,
                cost_s: 11.0,
            },
            Candidate {
                feasibility: 0.6,
                cost_s: 10.0,
            },
        ];
        let mut a = Argmax::new(40.0);
        assert!(a.best().is_none());
        for &x in &c {
            a.offer(x).unwrap();
        }
        let d: Decision<3> = select(40.0, &c).unwrap();
        assert_eq!(a.best().unwrap().index, d.chosen);
        assert_eq!(a.offered(), 3);
    }
}
