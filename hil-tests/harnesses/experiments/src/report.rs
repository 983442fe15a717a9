//! The summary as the markdown report (docs/experiments.md).

use super::*;

impl Summary {
    /// Aggregates records.
    pub fn from_records(cfg: &EvalConfig, records: &[TaskRecord]) -> Summary {
        let at = |speed: f64, m: MethodKind| {
            records
                .iter()
                .filter(move |r| r.speed_mps == speed && r.method == m.name())
        };
        let mut main = Vec::new();
        let mut points = Vec::new();
        for &m in &cfg.methods {
            main.push((m, None, Stats::of(at(cfg.main_speed_mps, m))));
            for d in Difficulty::ALL {
                let rs: Vec<&TaskRecord> = at(cfg.main_speed_mps, m)
                    .filter(|r| r.difficulty == d)
                    .collect();
                main.push((m, Some(d), Stats::of(rs.iter().copied())));
                // Each Fig. 5 point is the average of 10 tasks (task id order).
                for chunk in rs.chunks(10) {
                    let s = Stats::of(chunk.iter().copied());
                    points.push((m, d, s.mean_time_s, s.completion));
                }
            }
        }
        let mut paired = Vec::new();
        let grop: Vec<&TaskRecord> = at(cfg.main_speed_mps, MethodKind::Grop).collect();
        let grop_plus: Vec<&TaskRecord> = at(cfg.main_speed_mps, MethodKind::GropPlus).collect();
        let mut plus = Vec::new();
        if !grop.is_empty() && !grop_plus.is_empty() {
            plus.push((None, PlusDiff::of(&grop_plus, &grop)));
            for d in Difficulty::ALL {
                let a: Vec<&TaskRecord> = grop_plus
                    .iter()
                    .copied()
                    .filter(|r| r.difficulty == d)
                    .collect();
                let b: Vec<&TaskRecord> =
                    grop.iter().copied().filter(|r| r.difficulty == d).collect();
                plus.push((Some(d), PlusDiff::of(&a, &b)));
            }
        }
        if !grop.is_empty() {
            for &m in cfg
                .methods
                .iter()
                .filter(|&&m| m != MethodKind::Grop && m != MethodKind::GropPlus)
            {
                let other: Vec<&TaskRecord> = at(cfg.main_speed_mps, m).collect();
                paired.push((m, None, PairedDiff::of(&grop, &other)));
                for d in Difficulty::ALL {
                    let g: Vec<&TaskRecord> =
                        grop.iter().copied().filter(|r| r.difficulty == d).collect();
                    let o: Vec<&TaskRecord> = other
                        .iter()
                        .copied()
                        .filter(|r| r.difficulty == d)
                        .collect();
                    paired.push((m, Some(d), PairedDiff::of(&g, &o)));
                }
            }
        }
        let mut sweep = Vec::new();
        for &s in &cfg.sweep_speeds_mps {
            for &m in &cfg.sweep_methods {
                sweep.push((s, m, Stats::of(at(s, m))));
            }
        }
        Summary {
            main,
            sweep,
            points,
            paired,
            plus,
        }
    }

    /// Stats of a method and group at the main speed.
    pub fn get(&self, m: MethodKind, d: Option<Difficulty>) -> Option<Stats> {
        self.main
            .iter()
            .find(|(mm, dd, _)| *mm == m && *dd == d)
            .map(|x| x.2)
    }

    /// GROP minus `m`, paired over tasks, in group `d` (None: all tasks).
    pub fn paired_get(&self, m: MethodKind, d: Option<Difficulty>) -> Option<PairedDiff> {
        self.paired
            .iter()
            .find(|(mm, dd, _)| *mm == m && *dd == d)
            .map(|x| x.2)
    }

    /// GROP+ minus GROP, paired over tasks, in group `d` (None: all tasks).
    pub fn plus_get(&self, d: Option<Difficulty>) -> Option<PlusDiff> {
        self.plus.iter().find(|(dd, _)| *dd == d).map(|x| x.1)
    }

    /// Stats of the sweep.
    pub fn sweep_get(&self, speed: f64, m: MethodKind) -> Option<Stats> {
        self.sweep
            .iter()
            .find(|(s, mm, _)| *s == speed && *mm == m)
            .map(|x| x.2)
    }

    /// The expectations, each with whether the measurement supports it.
    pub fn checks(&self, cfg: &EvalConfig) -> Vec<(String, bool)> {
        let mut out = Vec::new();
        let g = MethodKind::Grop;
        for d in Difficulty::ALL {
            if let Some(gs) = self.get(g, Some(d)) {
                let best_other = cfg
                    .methods
                    .iter()
                    .filter(|&&m| m != g && m != MethodKind::GropPlus)
                    .filter_map(|&m| self.get(m, Some(d)).map(|s| (m, s.completion)))
                    .max_by(|a, b| a.1.total_cmp(&b.1));
                if let Some((m, c)) = best_other {
                    let diff = self.paired_get(m, Some(d)).unwrap_or_default();
                    out.push((
                        format!(
                            "{}: GROP has the highest completion ({:.3} vs best other {} {:.3}; \
                             paired difference {:+.3} ± {:.3} standard error)",
                            d.name(),
                            gs.completion,
                            m.name(),
                            c,
                            diff.mean,
                            diff.std_error
                        ),
                        gs.completion > c,
                    ));
                }
            }
        }
        if let (Some(gs), Some(ps)) = (self.get(g, None), self.get(MethodKind::Petlon, None)) {
            out.push((
                format!(
                    "GROP's time within 10% of PETLON's ({:.1} s vs {:.1} s)",
                    gs.mean_time_s, ps.mean_time_s
                ),
                gs.mean_time_s <= 1.1 * ps.mean_time_s,
            ));
        }
        if let (Some(gs), Some(ds)) = (self.get(g, None), self.get(MethodKind::Dvh, None)) {
            out.push((
                format!(
                    "GROP's time below DVH's ({:.1} s vs {:.1} s)",
                    gs.mean_time_s, ds.mean_time_s
                ),
                gs.mean_time_s < ds.mean_time_s,
            ));
        }
        let mut speeds = cfg.sweep_speeds_mps.clone();
        speeds.sort_by(f64::total_cmp);
        let comps: Vec<f64> = speeds
            .iter()
            .filter_map(|&s| self.sweep_get(s, g).map(|x| x.completion))
            .collect();
        if comps.len() >= 2 {
            let rising = comps.windows(2).all(|w| w[1] >= w[0]);
            let txt: Vec<String> = comps.iter().map(|c| format!("{c:.3}")).collect();
            out.push((
                format!("GROP's completion rises with speed ({})", txt.join(" -> ")),
                rising,
            ));
        }
        // Issue 13: GROP+ on the hard third.
        let hard = Some(Difficulty::Hard);
        if let (Some(p), Some(gs), Some(d)) = (
            self.get(MethodKind::GropPlus, hard),
            self.get(g, hard),
            self.plus_get(hard),
        ) {
            out.push((
                format!(
                    "hard: GROP+ places at least 0.90 of the objects ({:.3}; GROP {:.3}; paired {:+.3} ± {:.3})",
                    p.completion, gs.completion, d.completion.mean, d.completion.std_error
                ),
                p.completion >= 0.90,
            ));
            out.push((
                format!(
                    "hard: GROP+ places all three in at least 0.75 of the tasks ({:.3}; GROP {:.3}; paired {:+.3} ± {:.3})",
                    p.all_placed, gs.all_placed, d.all_placed.mean, d.all_placed.std_error
                ),
                p.all_placed >= 0.75,
            ));
            out.push((
                format!(
                    "hard: GROP+'s mean task time no higher than GROP's ({:.1} s vs {:.1} s; paired {:+.1} ± {:.1} s)",
                    p.mean_time_s, gs.mean_time_s, d.time_s.mean, d.time_s.std_error
                ),
                p.mean_time_s <= gs.mean_time_s,
            ));
        }
        out
    }

    /// Markdown tables: main comparison by difficulty, speed sweep (Table I), checks.
    #[allow(
        clippy::too_many_lines,
        reason = "the report's sections in the order they are printed"
    )]
    pub fn markdown(&self, cfg: &EvalConfig) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Main comparison at {} m/s: completion (objects placed) / all three placed / mean time (s) ± std\n",
            cfg.main_speed_mps
        );
        let _ = writeln!(
            s,
            "| method | easy | normal | hard | all | decide: nav-planner calls |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|");
        for &m in &cfg.methods {
            let cell = |d| {
                self.get(m, d)
                    .map(|x| {
                        format!(
                            "{:.3} / {:.3} / {:.1} ± {:.1}",
                            x.completion, x.all_placed, x.mean_time_s, x.std_time_s
                        )
                    })
                    .unwrap_or_default()
            };
            let calls = self.get(m, None).map(|x| x.mean_calls).unwrap_or(0.0);
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {:.1} |",
                m.name(),
                cell(Some(Difficulty::Easy)),
                cell(Some(Difficulty::Normal)),
                cell(Some(Difficulty::Hard)),
                cell(None),
                calls
            );
        }
        if !self.paired.is_empty() {
            let _ = writeln!(
                s,
                "\nGROP minus each method, completion paired over the same tasks: mean difference ± standard error\n"
            );
            let _ = writeln!(s, "| method | easy | normal | hard | all |");
            let _ = writeln!(s, "|---|---|---|---|---|");
            for &m in cfg
                .methods
                .iter()
                .filter(|&&m| m != MethodKind::Grop && m != MethodKind::GropPlus)
            {
                let cell = |d| {
                    self.paired_get(m, d)
                        .map(|x| format!("{:+.3} ± {:.3}", x.mean, x.std_error))
                        .unwrap_or_default()
                };
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} |",
                    m.name(),
                    cell(Some(Difficulty::Easy)),
                    cell(Some(Difficulty::Normal)),
                    cell(Some(Difficulty::Hard)),
                    cell(None)
                );
            }
        }
        if !self.plus.is_empty() {
            let p = cfg.planner.plus;
            let _ = writeln!(
                s,
                "\nGROP+ (retries {}, goal draws {}, goal margin {} m, R follows speed {}) minus GROP, paired over the same tasks: completion / all placed / time (s), mean difference ± standard error\n",
                p.max_retries,
                p.goal_draws.map_or_else(
                    || format!("GROP's ({})", cfg.planner.goal_draws),
                    |n| n.to_string()
                ),
                p.goal_margin_m,
                if p.r_follows_speed { "on" } else { "off" }
            );
            let _ = writeln!(s, "| group | completion | all placed | time (s) |");
            let _ = writeln!(s, "|---|---|---|---|");
            for d in [
                Some(Difficulty::Easy),
                Some(Difficulty::Normal),
                Some(Difficulty::Hard),
                None,
            ] {
                if let Some(x) = self.plus_get(d) {
                    let _ = writeln!(
                        s,
                        "| {} | {:+.3} ± {:.3} | {:+.3} ± {:.3} | {:+.1} ± {:.1} |",
                        d.map_or("all", Difficulty::name),
                        x.completion.mean,
                        x.completion.std_error,
                        x.all_placed.mean,
                        x.all_placed.std_error,
                        x.time_s.mean,
                        x.time_s.std_error
                    );
                }
            }
        }
        if !self.sweep.is_empty() {
            let _ = writeln!(
                s,
                "\nSpeed sweep (Table I), all tasks: completion / mean time (s)\n"
            );
            let _ = write!(s, "| speed |");
            for m in &cfg.sweep_methods {
                let _ = write!(s, " {} |", m.name());
            }
            let _ = write!(s, "\n|---|");
            for _ in &cfg.sweep_methods {
                let _ = write!(s, "---|");
            }
            let _ = writeln!(s);
            for &sp in &cfg.sweep_speeds_mps {
                let _ = write!(s, "| {sp} m/s |");
                for &m in &cfg.sweep_methods {
                    let cell = self
                        .sweep_get(sp, m)
                        .map(|x| format!("{:.3} / {:.1}", x.completion, x.mean_time_s));
                    let _ = write!(s, " {} |", cell.unwrap_or_default());
                }
                let _ = writeln!(s);
            }
        }
        let _ = writeln!(s, "\nThe issue's expectations, as measured:\n");
        for (text, ok) in self.checks(cfg) {
            let _ = writeln!(
                s,
                "- {} {}",
                if ok { "holds:" } else { "DOES NOT hold:" },
                text
            );
        }
        s
    }
}
