//! Property tests of the selection core against brute-force definitions.

use grop_select::{
    Candidate, Decision, UTILITY_TIE_EPS, select, smp_best_of, smp_index, task_feasibility,
};
use proptest::prelude::*;

fn heat() -> impl Strategy<Value = Vec<f32>> {
    prop::collection::vec(prop_oneof![Just(0.0_f32), 0.0_f32..=1.0], 1..200)
}

proptest! {
    /// F lies between 0 and the largest value, and is at least the mean of the positive values
    /// (Smp favours good cells, so its expectation cannot be below the plain mean).
    #[test]
    fn feasibility_bounds(v in heat()) {
        let f = task_feasibility(&v);
        let max = v.iter().cloned().fold(0.0_f32, f32::max) as f64;
        prop_assert!(f >= 0.0 && f <= max + 1e-9);
        let pos: Vec<f64> = v.iter().filter(|&&x| x > 0.0).map(|&x| x as f64).collect();
        if !pos.is_empty() {
            let mean = pos.iter().sum::<f64>() / pos.len() as f64;
            prop_assert!(f + 1e-9 >= mean);
        }
    }

    /// Over an evenly spaced grid of M uniforms, each cell is drawn M * v_i / sum(v) times up to
    /// one draw at each end: Smp draws proportionally to the heatmap value, never a zero cell.
    #[test]
    fn smp_is_proportional(v in heat()) {
        let total: f64 = v.iter().map(|&x| x as f64).sum();
        let m = 20_000usize;
        let mut counts = vec![0usize; v.len()];
        for k in 0..m {
            let u = (k as f64 + 0.5) / m as f64;
            match smp_index(&v, u) {
                Some(i) => counts[i] += 1,
                None => prop_assert!(total == 0.0),
            }
        }
        if total > 0.0 {
            for (i, &c) in counts.iter().enumerate() {
                let expected = m as f64 * v[i] as f64 / total;
                prop_assert!((c as f64 - expected).abs() <= 2.0 + 1e-6 * m as f64,
                    "cell {i}: {c} draws, expected {expected}");
                if v[i] == 0.0 { prop_assert_eq!(c, 0); }
            }
        }
    }

    /// Monte Carlo eq. 4 (mean heatmap value at Smp draws) converges to the closed form.
    #[test]
    fn closed_form_is_expectation_of_eq4(v in heat()) {
        let m = 20_000usize;
        let mut acc = 0.0;
        let mut n = 0;
        for k in 0..m {
            if let Some(i) = smp_index(&v, (k as f64 + 0.5) / m as f64) {
                acc += v[i] as f64;
                n += 1;
            }
        }
        if n > 0 {
            prop_assert!((acc / n as f64 - task_feasibility(&v)).abs() < 1e-3);
        }
    }

    /// Best-of-n never returns a worse cell than the first of its draws.
    #[test]
    fn best_of_n_dominates_single(v in heat(), us in prop::collection::vec(0.0_f64..1.0, 1..8)) {
        if let (Some(b), Some(s)) = (smp_best_of(&v, &us), smp_index(&v, us[0])) {
            prop_assert!(v[b] >= v[s]);
        }
    }

    /// `select` returns a candidate of maximal utility (up to the tie tolerance) and, among the
    /// tied ones, one of minimal cost, the first such.
    #[test]
    fn select_is_argmax(c in prop::collection::vec((0.0_f64..3.0, 0.0_f64..100.0), 1..64)) {
        let cands: Vec<Candidate> = c.iter()
            .map(|&(f, cost)| Candidate { feasibility: (f * 4.0).round() / 4.0, cost_s: cost.round() })
            .collect();
        let d: Decision<64> = select(40.0, &cands).unwrap();
        let u = |x: &Candidate| 40.0 * x.feasibility - x.cost_s;
        let best_u = cands.iter().map(u).fold(f64::NEG_INFINITY, f64::max);
        let chosen = &cands[d.chosen];
        prop_assert!(u(chosen) >= best_u - UTILITY_TIE_EPS);
        let tied_min_cost = cands.iter().filter(|x| u(x) >= best_u - UTILITY_TIE_EPS)
            .map(|x| x.cost_s).fold(f64::INFINITY, f64::min);
        prop_assert_eq!(chosen.cost_s, tied_min_cost);
        let first = cands.iter().position(|x| u(x) >= best_u - UTILITY_TIE_EPS && x.cost_s == tied_min_cost);
        prop_assert_eq!(Some(d.chosen), first);
    }
}
