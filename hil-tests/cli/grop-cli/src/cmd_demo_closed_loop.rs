//! `grop demo` as the closed loop: the world process (simulated clock, RMP on the virtual CAN
//! bus, UR5e on TCP, objects, camera, localisation) and the unchanged onboard processes
//! (perception + planning, executive) run one mission in simulated time. Shows live progress,
//! then prints the decision, each step's outcome and the latency of each stage, and draws the
//! route as driven with the outcomes.

use std::time::Duration;

use anyhow::Context;
use hil_world::mission::{self, MissionSpec};
use hil_world::objects::ObjectState;
use hil_world::report::{MissionEnd, WorldReport};
use indicatif::{ProgressBar, ProgressStyle};
use world::view;

use crate::cmd_demo::Args;
use crate::common;

fn parse_camera(s: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .with_context(|| format!("--camera {s:?}: expected WIDTHxHEIGHT"))?;
    Ok((
        w.parse().with_context(|| format!("--camera width {w:?}"))?,
        h.parse()
            .with_context(|| format!("--camera height {h:?}"))?,
    ))
}

/// Runs the closed-loop demo.
pub fn run(args: Args) -> anyhow::Result<()> {
    planner::methods::MethodKind::parse(&args.method).with_context(|| {
        format!(
            "unknown --method {:?}: use grop+, grop, satisficing, petlon, dvh or fcn-planning",
            args.method
        )
    })?;
    let (scene, robot) = args.world.load()?;
    anyhow::ensure!(
        ["none", "replan", "grop-plus"].contains(&args.retry.as_str()),
        "--retry {:?}: use grop-plus, none or replan",
        args.retry
    );
    // From any working directory: the committed model in the checkout.
    let model = common::committed_file_abs(&args.model, "the feasibility network")?;
    let bins = crate::common::mission_binaries(!args.no_build)?;
    let spec = MissionSpec {
        dir: args.run_dir.clone(),
        scene: scene.clone(),
        robot: robot.clone(),
        model,
        method: args.method.clone(),
        paper_smp: args.paper_smp,
        retry: args.retry.clone(),
        seed: args.world.seed,
        pace: args.wall_clock.then_some(1.0),
        camera_px: parse_camera(&args.camera)?,
        max_sim_s: args.max_sim_s,
        progress_s: 0.5,
        log: (!args.no_record).then(|| args.record.clone()),
        live: args.live,
        fault: args.fault,
        lidar: true,
        unmapped_chairs: Vec::new(),
        chair_moves: args.move_chair.clone(),
    };
    println!(
        "scene {:?}: {} chairs, {} objects; robot at {:.1} m/s, R = {}; method {}",
        scene.name,
        scene.chairs.len(),
        scene.targets.len(),
        robot.speed_mps,
        robot.success_bonus_r,
        args.method
    );
    if let Some(addr) = args.live {
        anyhow::ensure!(
            !args.no_record,
            "--live is served by the mission recorder: drop --no-record"
        );
        // A clear message before any process starts (the recorder says the same if the
        // address is taken between this check and its bind).
        if addr.port() != 0 {
            std::net::TcpListener::bind(addr).map_err(|e| {
                anyhow::anyhow!(
                    "--live {addr}: cannot listen there: {e} (choose another with --live ADDR)"
                )
            })?;
        }
    }
    let started = std::time::Instant::now();
    let mut running = mission::start(&spec, &bins)?;
    if spec.live.is_some() {
        let addr = running.live_addr(Duration::from_secs(30))?;
        println!("live view: ws://{addr} (Foxglove: Open connection; a viewer only)");
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} {elapsed_precise} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.enable_steady_tick(Duration::from_millis(100));
    let mut echo = |line: &str| {
        if let Some(rest) = line.strip_prefix("progress ") {
            bar.set_message(rest.to_owned());
        } else if line.starts_with('[') {
            bar.println(line);
        }
    };
    let report = running.finish(Duration::from_secs(900), &mut echo)?;
    bar.finish_and_clear();
    print_report(&report, started.elapsed(), spec.log.as_deref());
    for line in crate::mission_end::explain(&report, &args.run_dir) {
        println!("{line}");
    }
    let picture = draw(&args, &scene, &robot, &report);
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    picture
        .save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!(
        "wrote {} (run files in {})",
        args.out.display(),
        args.run_dir.display()
    );
    if report.end == MissionEnd::NeverStarted {
        anyhow::bail!(
            "the onboard processes never joined; see the logs in {}",
            args.run_dir.display()
        );
    }
    Ok(())
}

#[allow(clippy::too_many_lines, reason = "the printed report, line by line")]
fn print_report(report: &WorldReport, wall: Duration, spec_log: Option<&std::path::Path>) {
    if let Some(plan) = report.plans.first() {
        println!(
            "decision: plan {} with U = {:.1}, F = {:.2}, C = {:.1} s, decided in {:.2} ms (cut views + Psi + GROP)",
            plan.plan_id,
            plan.utility,
            plan.feasibility,
            plan.cost_s,
            plan.decision_us as f64 / 1e3
        );
        for (object, side, x, y, f) in &plan.unloads {
            let side = if *side > 0 { "near" } else { "far" };
            println!("  unload obj{object} from the {side} side at ({x:.2}, {y:.2}), F = {f:.2}");
        }
    }
    for p in report.plans.iter().skip(1) {
        println!(
            "replan at {:.1} s: plan {} ({} unloads), decided in {:.2} ms",
            p.t_s,
            p.plan_id,
            p.unloads.len(),
            p.decision_us as f64 / 1e3
        );
    }
    println!("steps:");
    for o in &report.objects {
        let what = match o.state {
            ObjectState::Released {
                verdict, error_m, ..
            } => {
                format!("{verdict:?}, {:.1} cm from its target", error_m * 100.0)
            }
            ObjectState::AtStation => "never loaded".into(),
            ObjectState::OnTray { .. } => "left on the tray (unload failed or given up)".into(),
            ObjectState::Held => "still in the gripper".into(),
        };
        println!("  obj{}: {what}", o.index);
    }
    for c in &report.collisions {
        println!(
            "  contact: {:?} at {:.1} s, base at ({:.2}, {:.2})",
            c.part, c.t_s, c.base[0], c.base[1]
        );
    }
    for d in &report.deaths {
        println!("  process {} died at {:.1} s", d.name, d.t_s);
    }
    let t = &report.timing;
    println!(
        "mission {:?}: placed {} of {} ({} without any contact on the way) in {:.1} s simulated, {:.1} s wall ({:.1}x real time); world step {:.0} us",
        report.end,
        report.placed_end_state,
        report.objects.len(),
        report.placed,
        t.sim_time_s,
        wall.as_secs_f64(),
        t.sim_time_s / wall.as_secs_f64().max(1e-9),
        t.world_step_us
    );
    println!("latency per stage:");
    if let Some(plan) = report.plans.first() {
        println!(
            "  perception + planning (wall): {:.2} ms",
            plan.decision_us as f64 / 1e3
        );
    }
    if let Some(s) = t.request_to_plan_s {
        println!("  plan request -> plan (simulated): {:.0} ms", s * 1e3);
    }
    if let Some(s) = t.plan_to_motion_s {
        println!("  plan -> base moving (simulated): {:.0} ms", s * 1e3);
    }
    let legs = &report.legs;
    if !legs.is_empty() {
        let n = legs.len() as f64;
        let rms = (legs
            .iter()
            .map(|l| {
                (l.realised[0] - l.commanded[0]).powi(2) + (l.realised[1] - l.commanded[1]).powi(2)
            })
            .sum::<f64>()
            / (2.0 * n))
            .sqrt();
        println!(
            "  {} legs: realised - commanded, rms per axis {:.3} m",
            legs.len(),
            rms
        );
    }
    if let Some(path) = spec_log {
        match grop_onboard::mission_log::MissionLog::read(path) {
            Ok(log) => println!(
                "mission log {}: {} messages, {:.1} MB{} (open it in Foxglove; `grop replay {}` re-runs the planner and the executive against it)",
                path.display(),
                log.messages.len(),
                std::fs::metadata(path).map(|m| m.len()).unwrap_or(0) as f64 / 1e6,
                if log.truncated.is_some() {
                    ", cut short"
                } else {
                    ""
                },
                path.display()
            ),
            Err(e) => println!("mission log: {e}"),
        }
    }
}

fn draw(
    args: &Args,
    scene: &world::Scene,
    robot: &world::RobotConfig,
    report: &WorldReport,
) -> view::RgbImage {
    let mut title = crate::picture::mission_title(
        "demo",
        &format!("scene {}", scene.name),
        &args.method.to_string(),
        args.world.seed,
        report,
    );
    if let Some(f) = &report.fault {
        title.push(format!("fault: {}", f.spec));
    }
    crate::picture::mission(scene, robot, report, args.pixels_per_m, title)
}
