//! `grop eval --suite full-setting`: whole table settings (8 and 12 place settings by default)
//! planned over several trips with the robot file's tray, executed in the trial simulator
//! (`experiments::full_setting`). Writes `settings_tasks.csv`, `summary.md` and `settings.svg` to
//! `<out-dir>/full-setting`, and with `--write-docs` to `docs/experiments/full-setting`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use experiments::full_setting::{
    SettingsEvalConfig, run_settings, settings_markdown, settings_svg, settings_tasks,
    write_settings_csv,
};
use planner::feasibility::{FcnEvaluator, FeasibilityEvaluator};
use planner::methods::{MethodKind, PlannerConfig};
use psi_eval::heuristics::{BinaryAnnulusEvaluator, BlurredAnnulusEvaluator, OracleEvaluator};

use crate::cmd_eval::{Args, Evaluator};

/// `grop eval --suite full-setting`.
pub fn run_command(args: Args) -> anyhow::Result<()> {
    let robot = crate::cmd_eval::load_robot(&args)?;
    let cfg = crate::cmd_eval::config(&args, &robot)?;
    anyhow::ensure!(
        args.shard.is_none(),
        "--shard runs the paper suite only (not --suite full-setting)"
    );
    run(&args, &robot, cfg.methods.clone(), cfg.planner)
}

pub fn run(
    args: &Args,
    robot: &world::RobotConfig,
    methods: Vec<MethodKind>,
    planner: PlannerConfig,
) -> anyhow::Result<()> {
    let started = Instant::now();
    let cfg = SettingsEvalConfig {
        seed: args.seed,
        settings: args.place_settings.clone(),
        tables_per_size: args.tables_per_size,
        methods,
        planner,
        robot: world::RobotConfig {
            speed_mps: args.speed,
            ..robot.clone()
        },
        ..SettingsEvalConfig::default()
    };
    let cfg = SettingsEvalConfig {
        planner: PlannerConfig {
            speed_mps: args.speed,
            ..cfg.planner
        },
        ..cfg
    };
    let mut psi: Box<dyn FeasibilityEvaluator> = match args.evaluator {
        Evaluator::Fcn => Box::new(
            FcnEvaluator::load(&crate::common::committed_file(&args.model))
                .with_context(|| format!("loading {}", args.model.display()))?,
        ),
        Evaluator::Oracle => Box::new(OracleEvaluator::new(
            args.trials_per_cell,
            args.seed ^ 0x6f72,
        )),
        Evaluator::Binary => Box::new(BinaryAnnulusEvaluator::new()),
        Evaluator::Blurred => Box::new(BlurredAnnulusEvaluator::new()),
        Evaluator::GroundTruth => {
            anyhow::bail!("the full-setting suite has no ground-truth heatmaps; use fcn or oracle")
        }
    };
    let tasks = settings_tasks(&cfg)?;
    log::info!(
        "{} tables ({:?} place settings), tray of {}, methods {:?}",
        tasks.len(),
        cfg.settings,
        cfg.robot.carry_capacity,
        cfg.methods.iter().map(|m| m.name()).collect::<Vec<_>>()
    );
    let records = run_settings(&cfg, &tasks, psi.as_mut())?;
    let mut md = format!(
        "# Full-setting suite\n\n<!-- written by `grop eval --suite full-setting` -->\n\n\
         Psi: {:?}; seed {}; speed {} m/s; R = {}; optimiser node limit {}. Completion = objects placed / \
         objects; time = execution in the trial simulator (navigation with sigma = {} m noise, {} s per load, \
         {} s per unload, {} s per failed navigation). Paired columns: the method minus {} on the same tables.\n",
        args.evaluator,
        cfg.seed,
        cfg.robot.speed_mps,
        cfg.planner.success_bonus_r,
        cfg.node_limit,
        cfg.robot.nav_noise_sigma_m,
        cfg.load_time_s,
        cfg.unload_time_s,
        cfg.failed_nav_time_s,
        cfg.methods.first().map(|m| m.name()).unwrap_or("-"),
    );
    md.push_str(&settings_markdown(&cfg, &records));
    print!("{md}");
    let mut dirs = vec![args.out_dir.join("full-setting")];
    if args.write_docs.is_some() {
        dirs.push(PathBuf::from("docs/experiments/full-setting"));
    }
    for dir in dirs {
        write_settings_csv(&dir.join("settings_tasks.csv"), &records)?;
        experiments::write_file(&dir.join("summary.md"), &md)?;
        settings_svg(&cfg, &records, &dir.join("settings.svg"))?;
        println!("wrote {}", dir.display());
    }
    log::info!("done in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}
