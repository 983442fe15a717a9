//! `grop demo`: the whole GROP pipeline once, on the simulated robot, and why it chose what it
//! chose. A scene (generated or from a file) is seen from above; the FCN (Psi) turns the crop of
//! every (target, side) into a heatmap; GROP (or a baseline) weighs feasibility against A* travel
//! time over all task plans (U = R F - C, eq. 1); the chosen plan gets its arm trajectories; then
//! the plan is executed in the trial simulator with navigation noise. Prints the decision (F, C, U
//! per location and the top plans) and writes a picture of heatmaps, paths, goals and outcomes.
//! This is `--in-process`; by default `grop demo` runs the closed loop (`cmd_demo_closed_loop`).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use experiments::{EvalConfig, StepOutcome};
use planner::costs::GridTravelTime;
use planner::feasibility::FcnEvaluator;
use planner::methods::{MethodKind, Planner, PlannerConfig, TaskMotionPlanner};
use planner::problem::TaskProblem;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use world::nav::OccupancyGrid;
use world::view::{self, Heatmap, RgbImage, RoomView};

use crate::{common, picture};

/// Arguments of `grop demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub world: common::SceneArgs,
    /// The feasibility network Psi (ONNX).
    #[arg(long, default_value = "models/psi-fcn.onnx")]
    pub model: PathBuf,
    /// Planning method: grop+ (GROP with retries and best-of-n goals, the default), grop (the
    /// paper's Algorithm 1), satisficing, petlon, dvh, fcn-planning.
    #[arg(long, default_value = "grop+")]
    pub method: String,
    /// GROP draws its goal from the whole heatmap, as the paper does, instead of from the
    /// obstacle-free cells only (the default).
    #[arg(long)]
    pub paper_smp: bool,
    /// Plans to list in the explanation (best utility first).
    #[arg(long, default_value_t = 8)]
    pub top: usize,
    /// Output PNG.
    #[arg(long, default_value = "out/demo.png")]
    pub out: PathBuf,
    /// Picture resolution (pixels per metre).
    #[arg(long, default_value_t = 48.0)]
    pub pixels_per_m: f64,
    /// Run the pipeline as one in-process calculation (the trial simulator, as `grop eval`
    /// does) instead of the closed loop of processes.
    #[arg(long)]
    pub in_process: bool,
    /// After a failed unload: `grop-plus` (GROP+'s retry policy, the default), `none` (the
    /// paper: go on with the rest) or `replan`.
    #[arg(long, default_value = "grop-plus")]
    pub retry: String,
    /// Run at wall-clock pace (1 simulated second per second) instead of as fast as the
    /// processes compute.
    #[arg(long)]
    pub wall_clock: bool,
    /// Camera frame size, WIDTHxHEIGHT.
    #[arg(long, default_value = "640x480")]
    pub camera: String,
    /// Folder for the run's files (scene, deployment, logs, world report).
    #[arg(long, default_value = "out/demo-run")]
    pub run_dir: PathBuf,
    /// Do not run `cargo build` for the world and the onboard binaries first.
    #[arg(long)]
    pub no_build: bool,
    /// The mission log (MCAP: every topic, every CAN frame, the arm's calls; open it in
    /// Foxglove, or `grop replay` it).
    #[arg(long, value_name = "FILE", default_value = "out/demo.mcap")]
    pub record: PathBuf,
    /// Do not write the mission log.
    #[arg(long)]
    pub no_record: bool,
    /// Watch the mission live in the Foxglove app (Open connection -> ws://ADDR): the recorder
    /// serves every channel of the mission log over the Foxglove WebSocket protocol, as a
    /// viewer only. ADDR defaults to 127.0.0.1:8765; off without the flag.
    #[arg(
        long,
        value_name = "ADDR",
        num_args = 0..=1,
        default_missing_value = "127.0.0.1:8765",
        require_equals = false
    )]
    pub live: Option<std::net::SocketAddr>,
    /// Simulated time limit of the mission, s.
    #[arg(long, default_value_t = 600.0)]
    pub max_sim_s: f64,
    /// Inject a fault into the closed loop: KIND, KIND@driving, KIND@arm, KIND@gripping or KIND@SECONDS
    /// (e.g. `can-silent`, `second-commander`, `rtde-silent`; docs/reliability.md lists all).
    #[arg(long, value_name = "KIND[@WHEN]")]
    pub fault: Option<hil_world::faults::FaultSpec>,
    /// Move a chair during the closed-loop mission, after the overhead frame was taken:
    /// AT_S:CHAIR:X:Y:YAW (simulated seconds, the chair's index in the scene, where it goes);
    /// repeat for more. The range sensor sees it, the onboard map does not.
    #[arg(long = "move-chair", value_name = "AT_S:CHAIR:X:Y:YAW")]
    pub move_chair: Vec<hil_world::moves::ChairMove>,
}

/// The pipeline once as one calculation (the fast model `grop eval` uses): no processes
/// (`--in-process`; the closed loop is `cmd_demo_closed_loop`).
pub fn run_in_process(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.live.is_none(),
        "--live needs the closed loop of processes (the recorder serves it), not --in-process"
    );
    let method = MethodKind::parse(&args.method).with_context(|| {
        format!(
            "unknown --method {:?}: use grop+, grop, satisficing, petlon, dvh or fcn-planning",
            args.method
        )
    })?;
    let (scene, robot) = args.world.load()?;
    let targets: Vec<[f64; 3]> = scene.targets.iter().map(|t| t.as_array()).collect();
    let mut psi = FcnEvaluator::load(&crate::common::committed_file(&args.model))
        .with_context(|| format!("loading the feasibility network {}", args.model.display()))?;

    // The map: occupancy grid and its corner visibility graph, built once per map.
    let map_started = Instant::now();
    let grid = OccupancyGrid::from_scene(&scene, &robot);
    let map_built = map_started.elapsed();

    // Perception + planning: what the planner node does on the robot for each task.
    let started = Instant::now();
    let problem = TaskProblem::from_world(&scene, &robot, &targets, &mut psi)?;
    let perceived = started.elapsed();
    let mut travel = GridTravelTime::new(&grid, robot.speed_mps);
    let config = PlannerConfig {
        free_goals_only: !args.paper_smp,
        ..PlannerConfig::for_robot(&robot)
    };
    let planned = Planner::new(method, config).plan(&problem, &mut travel, args.world.seed)?;
    let decided = started.elapsed();
    println!(
        "scene {:?}: {} chairs, {} objects; robot at {:.1} m/s, R = {}",
        scene.name,
        scene.chairs.len(),
        targets.len(),
        robot.speed_mps,
        config.success_bonus_r
    );
    println!(
        "decision in {:.1} ms ({:.1} ms of it rendering crops and running Psi on {} crops); \
         map built once in {:.1} ms ({} corner cells)",
        decided.as_secs_f64() * 1e3,
        perceived.as_secs_f64() * 1e3,
        problem.locations.len(),
        map_built.as_secs_f64() * 1e3,
        grid.corner_count()
    );
    print!("{}", planned.explain(args.top));

    // Arm trajectories for the chosen plan (IK + RRT-Connect from the carry pose).
    for (step, motion) in planned
        .plan
        .unloads
        .iter()
        .zip(planner::arm::arm_trajectories(
            &scene,
            &robot,
            &problem,
            &planned,
            args.world.seed,
        ))
    {
        match motion {
            Ok(m) => println!(
                "  arm for obj{} @ {}: {} joint waypoints to place",
                step.object,
                step.side.name(),
                m.path.len()
            ),
            Err(e) => println!(
                "  arm for obj{} @ {}: no motion from the commanded goal ({e})",
                step.object,
                step.side.name()
            ),
        }
    }

    // Execution in the simulator, with the paper's navigation noise.
    let eval = EvalConfig {
        robot: robot.clone(),
        planner: config,
        ..EvalConfig::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(args.world.seed);
    // GROP+ retries a failed unload where its retry policy says; the other methods do not.
    let retry = (method == MethodKind::GropPlus).then_some(&config);
    let execution = experiments::execute(
        &eval, &scene, &robot, &grid, &problem, &planned, retry, &mut rng,
    );
    for (object, outcome) in &execution.steps {
        println!("  executed obj{object}: {outcome:?}");
    }
    println!(
        "placed {} of {} objects in {:.1} s ({:.1} m driven)",
        execution.placed,
        targets.len(),
        execution.time_s,
        execution.distance_m
    );

    let picture = draw(&args, &scene, &grid, &problem, &planned, &execution.steps);
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    picture
        .save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!("wrote {}", args.out.display());
    Ok(())
}

/// Room, every location's predicted heatmap, the planned route (start -> station -> goals in
/// plan order, as the trial simulator drives it), each goal ringed with its F and coloured by
/// its outcome, the targets labelled, a metre scale and the legend.
#[allow(clippy::too_many_lines, reason = "one picture drawn layer by layer")]
fn draw(
    args: &Args,
    scene: &world::Scene,
    grid: &OccupancyGrid,
    problem: &TaskProblem,
    planned: &planner::methods::PlannedTask,
    steps: &[(usize, Vec<StepOutcome>)],
) -> RgbImage {
    let room = RoomView::whole_room(scene, args.pixels_per_m);
    let mut img = view::render_room(scene, &room);
    let s = f64::from(picture::text_scale(&img));
    for location in &problem.locations {
        let mut heatmap = Heatmap::zeros();
        for (cell, value) in location.cells.iter().zip(location.heat) {
            heatmap.set(cell.row, cell.col, value);
        }
        view::overlay_heatmap(
            &mut img,
            &room,
            location.target[0],
            location.side,
            &heatmap,
            true,
        );
    }
    let mut points = vec![problem.start_xy, problem.station_xy];
    points.extend(planned.plan.unloads.iter().map(|u| planned.goal_of(u).xy));
    let mut routed = vec![points[0]];
    for leg in points.windows(2) {
        match grid.plan(leg[0], leg[1]) {
            Some(path) => routed.extend(path.points.iter().skip(1)),
            None => routed.push(leg[1]),
        }
    }
    picture::route(&mut img, &room, &routed, picture::PLANNED, 2.0 * s, true);
    let mut labels = picture::Labels::default();
    let table_y = 0.5 * (scene.banquet_table.y_min_m() + scene.banquet_table.y_max_m());
    let mut stories = Vec::new();
    for (step, (object, outcome)) in planned.plan.unloads.iter().zip(steps) {
        let goal = planned.goal_of(step);
        // The first attempt's colour: placed there, or not (a retry went elsewhere).
        let placed = outcome.first() == Some(&StepOutcome::Placed);
        let colour = if placed {
            picture::PLACED
        } else {
            picture::FAILED
        };
        picture::ring(&mut img, &room, goal.xy, 0.16, 1.5 * s, colour);
        labels.keep_clear(&room, goal.xy, 0.2);
        let f = planned
            .locations
            .iter()
            .find(|l| l.object == step.object && l.side == step.side)
            .map_or(f64::NAN, |l| l.feasibility);
        labels.add(
            &img,
            &room,
            goal.xy,
            &format!("F {f:.2}"),
            colour,
            goal.xy.1 >= table_y,
        );
        let t = scene.targets[*object];
        let word = if outcome.contains(&StepOutcome::Placed) {
            "placed"
        } else {
            "failed"
        };
        let colour = if word == "placed" {
            picture::PLACED
        } else {
            picture::FAILED
        };
        view::draw_marker(&mut img, &room, t.x_m, t.y_m, 0.1, colour);
        labels.keep_clear(&room, (t.x_m, t.y_m), 0.12);
        labels.add(
            &img,
            &room,
            (t.x_m, t.y_m),
            &format!("obj{object} {word}"),
            colour,
            t.y_m < table_y,
        );
        let tries: Vec<String> = outcome.iter().map(|o| format!("{o:?}")).collect();
        let story = match outcome.as_slice() {
            [StepOutcome::Placed] => "placed from the first goal".to_owned(),
            _ => format!("{word} (tries: {})", tries.join(", then ")),
        };
        stories.push((
            picture::Swatch::Disc(colour),
            format!("obj{object}: {story}"),
        ));
    }
    labels.draw(&mut img);
    picture::scale_bar(&mut img, &room);
    let mut legend = picture::Legend {
        title: vec![
            format!("grop demo --in-process: scene {}", scene.name),
            format!("method {}, seed {}", planned.method.name(), args.world.seed),
            format!(
                "placed {} of {} (trial simulator)",
                steps
                    .iter()
                    .filter(|(_, o)| o.contains(&StepOutcome::Placed))
                    .count(),
                scene.targets.len()
            ),
        ],
        entries: Vec::new(),
    };
    legend
        .entry(picture::Swatch::Heat, "Psi's F of a standing cell, 0 to 1")
        .entry(picture::Swatch::Dashed(picture::PLANNED), "planned route")
        .entry(
            picture::Swatch::Ring(picture::PLACED),
            "standing spot with its F: placed from it",
        )
        .entry(
            picture::Swatch::Ring(picture::FAILED),
            "standing spot with its F: failed there",
        )
        .entry(picture::Swatch::Disc(picture::PLACED), "target: placed")
        .entry(picture::Swatch::Disc(picture::FAILED), "target: failed")
        .room();
    legend.entries.extend(stories);
    picture::with_legend(&img, &legend)
}
