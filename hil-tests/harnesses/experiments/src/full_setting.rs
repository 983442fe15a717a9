//! The full-setting suite (issue 13): whole table settings of 8 and 12 place settings (24 and 36
//! objects, [`world::table_settings`]) planned over several trips with a tray of the robot file's
//! capacity ([`planner::trip_methods`]), each plan executed in the trial simulator with
//! navigation noise, trip by trip.
//!
//! The method list is data ([`SettingsEvalConfig::methods`]): any [`MethodKind`] the multi-trip
//! planner knows runs, so a new method (GROP+) slots in by adding its kind.
//!
//! ```no_run
//! use experiments::full_setting::{SettingsEvalConfig, settings_tasks, run_settings, settings_markdown};
//! let cfg = SettingsEvalConfig::default();
//! let tasks = settings_tasks(&cfg)?;
//! let mut psi = planner::feasibility::FcnEvaluator::load(std::path::Path::new("models/psi-fcn.onnx"))?;
//! let records = run_settings(&cfg, &tasks, &mut psi)?;
//! println!("{}", settings_markdown(&cfg, &records));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::path::{Path, PathBuf};

use plotters::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use planner::costs::GridTravelTime;
use planner::feasibility::FeasibilityEvaluator;
use planner::methods::{MethodKind, PlannerConfig};
use planner::multi_trip::{DEFAULT_NODE_LIMIT, TripSearchLimits};
use planner::problem::{ProblemError, TaskProblem};
use planner::trip_methods::{MultiTripError, MultiTripPlanner, PlannedTrips};
use trial_sim::{TrialResult, TrialSimulator};
use world::generate::mix_seed;
use world::nav::OccupancyGrid;
use world::table_settings::{TableSettingsError, table_settings_suite};
use world::{RobotConfig, Scene};

use crate::StepOutcome;

/// The suite's settings. `Default`: 10 tables each of 8 and 12 place settings, all five methods,
/// the paper's robot (tray of 3), the main evaluation's manipulation and failure times.
#[derive(Debug, Clone)]
pub struct SettingsEvalConfig {
    /// Seed of scenes, goals, tie-breaks and navigation noise.
    pub seed: u64,
    /// Table sizes in place settings.
    pub settings: Vec<usize>,
    /// Tables per size.
    pub tables_per_size: usize,
    /// Methods, in report order.
    pub methods: Vec<MethodKind>,
    /// Planner settings (R, speed; sum aggregation).
    pub planner: PlannerConfig,
    /// The optimiser's node limit.
    pub node_limit: u64,
    /// The robot; its `carry_capacity` is the tray.
    pub robot: RobotConfig,
    /// Time to load one object (s).
    pub load_time_s: f64,
    /// Time of one unloading attempt (s).
    pub unload_time_s: f64,
    /// Time charged for a failed navigation (s).
    pub failed_nav_time_s: f64,
}

impl Default for SettingsEvalConfig {
    fn default() -> Self {
        let main = crate::EvalConfig::default();
        Self {
            seed: main.seed,
            settings: vec![8, 12],
            tables_per_size: 10,
            methods: MethodKind::ALL.to_vec(),
            planner: main.planner,
            node_limit: DEFAULT_NODE_LIMIT,
            robot: main.robot,
            load_time_s: main.load_time_s,
            unload_time_s: main.unload_time_s,
            failed_nav_time_s: main.failed_nav_time_s,
        }
    }
}

/// Why the suite failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SettingsEvalError {
    /// A configuration value is out of range.
    #[error("full-setting suite configuration: {0}")]
    Config(String),
    /// A table could not be generated.
    #[error("table settings: {0}")]
    Table(#[from] TableSettingsError),
    /// Psi or the problem failed on a table.
    #[error("table {task}: {source}")]
    Problem {
        /// Task id.
        task: usize,
        /// The error.
        source: ProblemError,
    },
    /// A planner failed on a table.
    #[error("{method} on table {task}: {source}")]
    Plan {
        /// The method.
        method: &'static str,
        /// Task id.
        task: usize,
        /// The error.
        source: MultiTripError,
    },
    /// Writing a result failed.
    #[error(transparent)]
    Eval(#[from] crate::EvalError),
}

/// One table to set.
#[derive(Debug, Clone)]
pub struct SettingsTask {
    /// Task id.
    pub id: usize,
    /// Place settings.
    pub settings: usize,
    /// The scene (targets = every item).
    pub scene: Scene,
    /// Its navigation grid.
    pub grid: OccupancyGrid,
}

/// The tables of the suite.
pub fn settings_tasks(cfg: &SettingsEvalConfig) -> Result<Vec<SettingsTask>, SettingsEvalError> {
    if cfg.settings.is_empty() || cfg.tables_per_size == 0 || cfg.methods.is_empty() {
        return Err(SettingsEvalError::Config(
            "need a table size, a table and a method".into(),
        ));
    }
    let mut tasks = Vec::new();
    for &settings in &cfg.settings {
        for scene in table_settings_suite(cfg.seed, settings, cfg.tables_per_size)? {
            let grid = OccupancyGrid::from_scene(&scene, &cfg.robot);
            tasks.push(SettingsTask {
                id: tasks.len(),
                settings,
                scene,
                grid,
            });
        }
    }
    Ok(tasks)
}

/// One (table, method) result: a CSV row.
#[derive(Debug, Clone, Serialize)]
pub struct SettingsRecord {
    /// Task id.
    pub task: usize,
    /// Place settings.
    pub settings: usize,
    /// Objects.
    pub objects: usize,
    /// Method name.
    pub method: &'static str,
    /// Trips planned.
    pub trips: usize,
    /// Objects placed.
    pub placed: usize,
    /// Execution time (s).
    pub time_s: f64,
    /// Distance driven (m).
    pub distance_m: f64,
    /// `F(p)` (expected objects placed, from Psi).
    pub predicted_f: f64,
    /// `C(p)` (s).
    pub predicted_cost_s: f64,
    /// `U(p)`.
    pub predicted_u: f64,
    /// The optimiser's gap bound (searching methods; 0 for the others).
    pub gap: f64,
    /// Proven optimal (searching methods).
    pub proven_optimal: bool,
    /// Step outcomes as `object:outcome` joined by `|`.
    pub steps: String,
}

/// Plans every table with every method and executes the plans. `psi` runs first, sequentially,
/// per table; planning and execution then run in parallel over tables.
pub fn run_settings(
    cfg: &SettingsEvalConfig,
    tasks: &[SettingsTask],
    psi: &mut dyn FeasibilityEvaluator,
) -> Result<Vec<SettingsRecord>, SettingsEvalError> {
    let capacity = cfg.robot.carry_capacity as usize;
    let problems: Vec<TaskProblem> = tasks
        .iter()
        .map(|t| {
            let targets: Vec<[f64; 3]> = t.scene.targets.iter().map(|x| x.as_array()).collect();
            TaskProblem::from_world(&t.scene, &cfg.robot, &targets, psi)
                .map_err(|source| SettingsEvalError::Problem { task: t.id, source })
        })
        .collect::<Result<_, _>>()?;
    let per_task: Result<Vec<Vec<SettingsRecord>>, SettingsEvalError> = tasks
        .par_iter()
        .zip(problems.par_iter())
        .map(|(task, problem)| {
            let mut out = Vec::with_capacity(cfg.methods.len());
            for &method in &cfg.methods {
                let mut travel = GridTravelTime::new(&task.grid, cfg.robot.speed_mps);
                let plan_seed = mix_seed(cfg.seed, task.id as u64, 0x7365_7470);
                let planner = MultiTripPlanner {
                    limits: TripSearchLimits {
                        max_nodes: cfg.node_limit,
                    },
                    ..MultiTripPlanner::new(method, cfg.planner, capacity)
                };
                let planned = planner
                    .plan(problem, &mut travel, plan_seed)
                    .map_err(|source| SettingsEvalError::Plan {
                        method: method.name(),
                        task: task.id,
                        source,
                    })?;
                // Same noise stream for every method (paired comparison).
                let mut rng =
                    ChaCha8Rng::seed_from_u64(mix_seed(cfg.seed, task.id as u64, 0x7365_7478));
                let exec = execute_trips(cfg, task, problem, &planned, &mut rng);
                out.push(SettingsRecord {
                    task: task.id,
                    settings: task.settings,
                    objects: problem.n_objects(),
                    method: method.name(),
                    trips: planned.plan.trips.len(),
                    placed: exec.placed,
                    time_s: exec.time_s,
                    distance_m: exec.distance_m,
                    predicted_f: planned.feasibility,
                    predicted_cost_s: planned.cost_s,
                    predicted_u: planned.utility,
                    gap: planned.search.map_or(0.0, |s| s.gap),
                    proven_optimal: planned.search.is_some_and(|s| s.proven_optimal),
                    steps: exec
                        .steps
                        .iter()
                        .map(|(o, s)| {
                            format!(
                                "{o}:{}",
                                serde_json::to_string(s)
                                    .unwrap_or_default()
                                    .trim_matches('"')
                            )
                        })
                        .collect::<Vec<_>>()
                        .join("|"),
                });
            }
            Ok(out)
        })
        .collect();
    Ok(per_task?.into_iter().flatten().collect())
}

/// Executes a multi-trip plan: per trip, drive to the station (from wherever the robot is), load,
/// then for each object drive to its goal (noisy end pose) and run the placing check of the trial
/// simulator. Failures are charged as in the main evaluation ([`crate::execute`]).
pub fn execute_trips(
    cfg: &SettingsEvalConfig,
    task: &SettingsTask,
    problem: &TaskProblem,
    planned: &PlannedTrips,
    rng: &mut ChaCha8Rng,
) -> crate::Execution {
    let speed = cfg.robot.speed_mps;
    let grid = &task.grid;
    let mut sim = TrialSimulator::new(&task.scene, &cfg.robot);
    let (mut time_s, mut distance_m, mut placed) = (0.0, 0.0, 0usize);
    let mut steps = Vec::new();
    let mut at = problem.start_xy;
    for trip in &planned.plan.trips {
        match grid.plan(at, problem.station_xy) {
            Some(p) => {
                time_s += p.travel_time_s(speed);
                distance_m += p.length_m;
                at = problem.station_xy;
            }
            None => {
                // Cannot reach the station: this trip's objects stay there.
                time_s += cfg.failed_nav_time_s;
                steps.extend(
                    trip.unloads
                        .iter()
                        .map(|u| (u.object, vec![StepOutcome::NoPath])),
                );
                continue;
            }
        }
        time_s += cfg.load_time_s * trip.load_order.len() as f64;
        for u in &trip.unloads {
            let goal = planned.goal_of(u);
            let target = problem.location(u.object, u.side).target;
            let Some(path) = grid.plan(at, goal.xy) else {
                time_s += cfg.failed_nav_time_s;
                steps.push((u.object, vec![StepOutcome::NoPath]));
                continue;
            };
            let outcome = sim.run(target, u.side, goal.xy, rng);
            let realised = (outcome.realised.x_m, outcome.realised.y_m);
            match outcome.result {
                TrialResult::BaseCollision => {
                    time_s += cfg.failed_nav_time_s;
                    distance_m += path.length_m;
                    steps.push((u.object, vec![StepOutcome::BaseCollision]));
                    at = goal.xy;
                }
                result => {
                    let end_leg = (realised.0 - goal.xy.0).hypot(realised.1 - goal.xy.1);
                    time_s += (path.length_m + end_leg) / speed + cfg.unload_time_s;
                    distance_m += path.length_m + end_leg;
                    if result == TrialResult::Success {
                        placed += 1;
                        steps.push((u.object, vec![StepOutcome::Placed]));
                    } else {
                        steps.push((u.object, vec![StepOutcome::ArmFailure]));
                    }
                    at = realised;
                }
            }
        }
    }
    // No retries here: over trips, a failed object stays on the tray (GROP+'s retry policy is
    // the single-trip executor's).
    crate::Execution {
        steps,
        retries: 0,
        placed,
        time_s,
        distance_m,
    }
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// Mean and 95% half-width (normal approximation) of paired differences.
fn paired(diffs: &[f64]) -> (f64, f64) {
    let m = mean(diffs);
    if diffs.len() < 2 {
        return (m, f64::NAN);
    }
    let var = diffs.iter().map(|d| (d - m).powi(2)).sum::<f64>() / (diffs.len() - 1) as f64;
    (m, 1.96 * (var / diffs.len() as f64).sqrt())
}

/// The suite's report: per table size and method, completion (objects placed / objects), time,
/// trips, the plan's predicted F, C, U, the optimiser's gap; and each method paired against the
/// first method of the list (GROP by default) on the same tables.
pub fn settings_markdown(cfg: &SettingsEvalConfig, records: &[SettingsRecord]) -> String {
    let mut md = String::new();
    let reference = cfg.methods.first().map(|m| m.name()).unwrap_or("");
    for &settings in &cfg.settings {
        let rows: Vec<&SettingsRecord> =
            records.iter().filter(|r| r.settings == settings).collect();
        let Some(objects) = rows.first().map(|r| r.objects) else {
            continue;
        };
        let tables = rows
            .iter()
            .map(|r| r.task)
            .collect::<std::collections::BTreeSet<_>>();
        md.push_str(&format!(
            "\n### {settings} place settings ({objects} objects, tray of {}, {} tables)\n\n\
             | method | completion | time (s) | trips | F(p) | C(p) (s) | U(p) | gap bound (mean / max) | proven optimal | completion vs {reference} (95% CI) | time vs {reference} (s, 95% CI) |\n\
             |---|---|---|---|---|---|---|---|---|---|---|\n",
            cfg.robot.carry_capacity,
            tables.len()
        ));
        for &m in &cfg.methods {
            let mine: Vec<&&SettingsRecord> =
                rows.iter().filter(|r| r.method == m.name()).collect();
            if mine.is_empty() {
                continue;
            }
            let f = |g: &dyn Fn(&SettingsRecord) -> f64| {
                mean(&mine.iter().map(|r| g(r)).collect::<Vec<_>>())
            };
            let completion = |r: &SettingsRecord| r.placed as f64 / r.objects as f64;
            let base = |task: usize| {
                rows.iter()
                    .find(|r| r.task == task && r.method == reference)
                    .copied()
            };
            let (dc, dc_ci) = paired(
                &mine
                    .iter()
                    .filter_map(|r| base(r.task).map(|b| completion(r) - completion(b)))
                    .collect::<Vec<_>>(),
            );
            let (dt, dt_ci) = paired(
                &mine
                    .iter()
                    .filter_map(|r| base(r.task).map(|b| r.time_s - b.time_s))
                    .collect::<Vec<_>>(),
            );
            let searched = m != MethodKind::Dvh && m != MethodKind::Satisficing;
            let gap_max = mine.iter().map(|r| r.gap).fold(0.0, f64::max);
            md.push_str(&format!(
                "| {} | {:.3} | {:.0} | {:.1} | {:.2} | {:.0} | {:.0} | {} | {} | {} | {} |\n",
                m.name(),
                f(&completion),
                f(&|r| r.time_s),
                f(&|r| r.trips as f64),
                f(&|r| r.predicted_f),
                f(&|r| r.predicted_cost_s),
                f(&|r| r.predicted_u),
                if searched {
                    format!("{:.1} / {:.1}", f(&|r| r.gap), gap_max)
                } else {
                    "-".into()
                },
                if searched {
                    format!(
                        "{}/{}",
                        mine.iter().filter(|r| r.proven_optimal).count(),
                        mine.len()
                    )
                } else {
                    "-".into()
                },
                if m.name() == reference {
                    "-".into()
                } else {
                    format!("{dc:+.3} ± {dc_ci:.3}")
                },
                if m.name() == reference {
                    "-".into()
                } else {
                    format!("{dt:+.0} ± {dt_ci:.0}")
                },
            ));
        }
    }
    md
}

/// Writes the records as CSV.
pub fn write_settings_csv(
    path: &Path,
    records: &[SettingsRecord],
) -> Result<(), SettingsEvalError> {
    let mut s = String::from(
        "task,settings,objects,method,trips,placed,time_s,distance_m,predicted_f,predicted_cost_s,predicted_u,gap,proven_optimal,steps\n",
    );
    for r in records {
        s.push_str(&format!(
            "{},{},{},{},{},{},{:.3},{:.3},{:.4},{:.3},{:.3},{:.4},{},{}\n",
            r.task,
            r.settings,
            r.objects,
            r.method,
            r.trips,
            r.placed,
            r.time_s,
            r.distance_m,
            r.predicted_f,
            r.predicted_cost_s,
            r.predicted_u,
            r.gap,
            r.proven_optimal,
            r.steps
        ));
    }
    crate::write_file(path, &s)?;
    Ok(())
}

/// Execution time against completion, one panel per table size, one point per table and method.
pub fn settings_svg(
    cfg: &SettingsEvalConfig,
    records: &[SettingsRecord],
    path: &Path,
) -> Result<(), SettingsEvalError> {
    let err = |e: &dyn std::fmt::Display| crate::EvalError::Plot {
        path: PathBuf::from(path),
        reason: e.to_string(),
    };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| crate::EvalError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    let root = SVGBackend::new(path, (1100, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let panels = root.split_evenly((1, cfg.settings.len().max(1)));
    let palette = [
        RGBColor(214, 39, 40),
        RGBColor(31, 119, 180),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
    ];
    for (panel, &settings) in panels.iter().zip(&cfg.settings) {
        let rows: Vec<&SettingsRecord> =
            records.iter().filter(|r| r.settings == settings).collect();
        let x_max = rows.iter().map(|r| r.time_s).fold(0.0, f64::max) * 1.05 + 1.0;
        let x_min = rows.iter().map(|r| r.time_s).fold(f64::INFINITY, f64::min) * 0.95;
        let x_min = if x_min.is_finite() { x_min } else { 0.0 };
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!("{settings} place settings ({} objects)", 3 * settings),
                ("sans-serif", 20),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(x_min..x_max, 0.0..1.05)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("execution time (s)")
            .y_desc("completion (placed / objects)")
            .draw()
            .map_err(|e| err(&e))?;
        for (i, &m) in cfg.methods.iter().enumerate() {
            let c = palette[i % palette.len()];
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.method == m.name())
                .map(|r| (r.time_s, r.placed as f64 / r.objects as f64))
                .collect();
            if pts.is_empty() {
                continue;
            }
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.mix(0.7).filled())))
                .map_err(|e| err(&e))?
                .label(m.name())
                .legend(move |(x, y)| Circle::new((x, y), 5, c.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_config_is_reported() {
        let cfg = SettingsEvalConfig {
            methods: Vec::new(),
            ..SettingsEvalConfig::default()
        };
        assert!(matches!(
            settings_tasks(&cfg),
            Err(SettingsEvalError::Config(_))
        ));
        let cfg = SettingsEvalConfig {
            settings: vec![13],
            ..SettingsEvalConfig::default()
        };
        assert!(matches!(
            settings_tasks(&cfg),
            Err(SettingsEvalError::Table(_))
        ));
    }

    #[test]
    fn a_small_suite_plans_and_executes_every_method() {
        let cfg = SettingsEvalConfig {
            settings: vec![2],
            tables_per_size: 2,
            ..SettingsEvalConfig::default()
        };
        let tasks = settings_tasks(&cfg).expect("tables");
        let mut psi = psi_eval::heuristics::BinaryAnnulusEvaluator::new();
        let records = run_settings(&cfg, &tasks, &mut psi).expect("runs");
        assert_eq!(records.len(), 2 * cfg.methods.len());
        for r in &records {
            assert_eq!(r.objects, 6);
            assert_eq!(r.trips, 2, "6 objects on a tray of 3");
            assert!(r.placed <= r.objects);
            assert_eq!(r.steps.split('|').count(), 6, "{}", r.steps);
            assert!(r.time_s > 0.0 && r.gap >= 0.0);
        }
        let again = run_settings(&cfg, &tasks, &mut psi).expect("runs");
        let key = |r: &SettingsRecord| (r.task, r.method, r.placed, r.time_s.to_bits());
        assert_eq!(
            records.iter().map(key).collect::<Vec<_>>(),
            again.iter().map(key).collect::<Vec<_>>(),
            "deterministic"
        );
        let md = settings_markdown(&cfg, &records);
        assert!(
            md.contains("2 place settings (6 objects") && md.contains("GROP"),
            "{md}"
        );
    }

    #[test]
    fn paired_differences() {
        let (m, ci) = paired(&[1.0, 3.0]);
        assert!((m - 2.0).abs() < 1e-12);
        assert!((ci - 1.96 * (2.0f64 / 2.0).sqrt()).abs() < 1e-12);
        assert!(paired(&[1.0]).1.is_nan());
    }
}
