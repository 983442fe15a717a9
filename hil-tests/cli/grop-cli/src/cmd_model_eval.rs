//! `grop model-eval`: measures feasibility evaluators (the FCN, the two geometric heuristics, the
//! simulator oracle) against ground truth simulated on freshly generated evaluation scenes, and
//! prints one markdown table (MAE, Brier, ECE, |F_hat - F|, expected success of Smp's goal).
//!
//! `grop model-eval --model models/psi-fcn.onnx --scenes 12 --targets 5 --trials 25`

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use planner::feasibility::{FcnEvaluator, FeasibilityEvaluator};
use psi_eval::evalset::{EvalSpec, build_eval_set, evaluate};
use psi_eval::heuristics::{BinaryAnnulusEvaluator, BlurredAnnulusEvaluator, OracleEvaluator};
use psi_eval::metrics::QualityReport;
use world::RobotConfig;

/// Arguments of `grop model-eval`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The FCN to measure (ONNX, as exported by models/training/train.py).
    #[arg(long, default_value = "models/psi-fcn.onnx")]
    model: PathBuf,
    /// Robot file (TOML); the built-in paper robot when absent.
    #[arg(long)]
    robot: Option<PathBuf>,
    /// Seed of the evaluation scenes and their ground truth (pick one datagen never used).
    #[arg(long, default_value_t = 9_000)]
    seed: u64,
    /// Evaluation scenes (cycling 15, 20, 25 chairs over both sides).
    #[arg(long, default_value_t = 12)]
    scenes: usize,
    /// Targets per scene; each is evaluated from both sides.
    #[arg(long, default_value_t = 5)]
    targets: usize,
    /// Ground-truth trials per candidate cell (at least 25 for reported numbers).
    #[arg(long, default_value_t = 25)]
    trials: u16,
    /// Evaluators to run, comma-separated: fcn, binary, blurred, oracle.
    #[arg(long, value_delimiter = ',', default_value = "fcn,binary,blurred")]
    evaluators: Vec<String>,
    /// Trials per cell of the oracle evaluator (its own seed, independent of the truth).
    #[arg(long, default_value_t = 5)]
    oracle_trials: u16,
    /// Also write the reports as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Fail unless the FCN meets the thresholds of this model card and beats the binary heuristic
    /// on MAE, Brier, ECE and |F_hat - F|.
    #[arg(long)]
    check_card: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let robot = match &args.robot {
        Some(p) => {
            RobotConfig::load(p).with_context(|| format!("loading robot file {}", p.display()))?
        }
        None => RobotConfig::default(),
    };
    if args.trials < 25 {
        log::warn!(
            "{} trials per cell: the reported numbers need at least 25",
            args.trials
        );
    }
    let spec = EvalSpec {
        seed: args.seed,
        scenes: args.scenes,
        targets_per_scene: args.targets,
        trials_per_cell: args.trials,
        ..EvalSpec::default()
    };
    let t = Instant::now();
    let set = build_eval_set(&robot, &spec).context("building the evaluation set")?;
    log::info!(
        "ground truth: {} tasks x 192 cells x {} trials in {:.1} s",
        set.tasks.len(),
        args.trials,
        t.elapsed().as_secs_f64()
    );
    let mut reports: Vec<QualityReport> = Vec::new();
    for name in &args.evaluators {
        let mut evaluator: Box<dyn FeasibilityEvaluator> = match name.as_str() {
            "fcn" => Box::new(
                FcnEvaluator::load(&crate::common::committed_file(&args.model))
                    .with_context(|| format!("loading {}", args.model.display()))?,
            ),
            "binary" => Box::new(BinaryAnnulusEvaluator::new()),
            "blurred" => Box::new(BlurredAnnulusEvaluator::new()),
            "oracle" => Box::new(OracleEvaluator::new(
                args.oracle_trials,
                args.seed ^ 0x6f72_6163,
            )),
            other => bail!("unknown evaluator `{other}` (fcn, binary, blurred, oracle)"),
        };
        let t = Instant::now();
        let report = evaluate(evaluator.as_mut(), &set)
            .with_context(|| format!("running evaluator {name}"))?;
        log::info!(
            "{name}: {:.2} s for {} tasks",
            t.elapsed().as_secs_f64(),
            set.tasks.len()
        );
        reports.push(report);
    }
    println!(
        "{} tasks ({} scenes x {} targets x 2 sides), {} labelled cells each, truth from {} trials per cell, seed {}\n",
        set.tasks.len(),
        args.scenes,
        args.targets,
        192,
        args.trials,
        args.seed
    );
    println!("{}", QualityReport::markdown_header());
    for r in &reports {
        println!("{}", r.markdown_row());
    }
    if let Some(r) = reports.first() {
        println!("{}", r.markdown_truth_row());
    }
    if let Some(path) = &args.json {
        let doc = serde_json::json!({ "spec": spec, "model": args.model, "reports": reports });
        std::fs::write(path, serde_json::to_string_pretty(&doc)? + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(card) = &args.check_card {
        check_card(card, &reports)?;
    }
    Ok(())
}

fn check_card(card: &std::path::Path, reports: &[QualityReport]) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(crate::common::committed_file(card))
        .with_context(|| format!("reading model card {}", card.display()))?;
    let bounds = psi_eval::thresholds::parse_model_card(&text)
        .with_context(|| format!("in {}", card.display()))?;
    let fcn = reports
        .iter()
        .find(|r| r.evaluator == "fcn")
        .context("--check-card needs the fcn evaluator")?;
    let mut problems = psi_eval::thresholds::violations(fcn, &bounds);
    if let Some(bin) = reports.iter().find(|r| r.evaluator == "binary-annulus") {
        // The success of Smp's proportional draws is reported, not required: a calibrated map
        // (the true heatmap included) spreads goals over marginal cells that a binary map's
        // uniform draws avoid (docs/fcn.md, "Quality").
        for line in psi_eval::thresholds::not_better_than(fcn, bin) {
            if line.starts_with("smp_success") {
                println!("note: {line}");
            } else {
                problems.push(line);
            }
        }
    }
    if problems.is_empty() {
        println!(
            "\nmodel card {}: all {} thresholds met",
            card.display(),
            bounds.len()
        );
        Ok(())
    } else {
        bail!(
            "model card {} not met:\n  {}",
            card.display(),
            problems.join("\n  ")
        )
    }
}
