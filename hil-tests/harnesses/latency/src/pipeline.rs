//! Pipeline latency on the wall clock: a real-size camera frame (640 x 480 RGB8, the scene
//! rendered by the world's camera) stamped and published, a plan request right behind it, and
//! the planning node (`grop_onboard::planner_node`, the code `grop-planner` runs, on the wall
//! clock, so it wakes on the frame) cutting its views, running Psi and GROP and publishing the
//! plan: frame stamp to the plan held by a subscriber. Every sample uses a new frame (its id is
//! checked in the plan) and a new request.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use grop_ipc::{CameraFrameMsg, IpcNode, ReplanReason, ReplanRequestMsg, TaskPlanMsg};
use grop_onboard::deployment::PlannerSettings;
use grop_onboard::planner_node::PlannerNode;

use crate::stats::Summary;
use crate::{BenchError, Step};

/// What [`frame_to_plan`] measured.
#[derive(Debug, Clone)]
pub struct PipelineResult {
    /// `no RT settings` or the settings' spec.
    pub setting: String,
    /// Frame stamp to the plan held by the subscriber.
    pub frame_to_plan: Summary,
    /// The planner's own decision time (cut views + Psi + GROP), from the plans.
    pub decision: Summary,
}

fn monotonic_ns() -> u64 {
    grop_clock::duration_ns(grop_clock::monotonic_now())
}

/// Runs `samples` frame-to-plan measurements with the model at `model` on an evaluation scene;
/// with `rt`, the planner's thread first applies those real-time settings (SCHED_FIFO applies
/// to that thread).
#[allow(
    clippy::too_many_lines,
    reason = "one benchmark: setup, the measured loop, the statistics"
)]
pub fn frame_to_plan(
    samples: usize,
    model: &Path,
    namespace: &str,
    rt: Option<grop_clock::rt::RtSettings>,
) -> Result<PipelineResult, BenchError> {
    let scene = world::generate::evaluation_scene(7, 15, 3);
    let robot = world::RobotConfig::default();
    let harness = IpcNode::new(namespace, "latency-pipeline").step("iceoryx2")?;
    let frames = harness
        .publisher::<CameraFrameMsg>()
        .step("the frame publisher")?;
    let requests = harness
        .publisher::<ReplanRequestMsg>()
        .step("the request publisher")?;
    let plans = harness
        .subscriber::<TaskPlanMsg>()
        .step("the plan subscriber")?;

    let camera = world::camera::OverheadCamera::fitting_room_with(&scene, 640, 480);
    let mut image = vec![0u8; camera.rgb8_len()];
    world::camera::render_frame(&scene, &camera, &mut image).step("rendering the frame")?;

    let stop = Arc::new(AtomicBool::new(false));
    let node_stop = Arc::clone(&stop);
    let (ready_tx, ready) = std::sync::mpsc::channel::<Result<(), String>>();
    let (node_scene, node_model, node_ns) = (scene.clone(), model.to_owned(), namespace.to_owned());
    // The node lives on its own thread (Psi's evaluator is not Send): built there, run there.
    let planner = std::thread::Builder::new()
        .name("planner-node".into())
        .spawn(move || -> Result<(), String> {
            let policy = match rt {
                Some(settings) => {
                    let report = grop_clock::rt::apply(&settings);
                    if !report.all_applied() {
                        log::warn!("pipeline: real-time settings partly refused:\n{report}");
                    }
                    grop_clock::rt::current_policy()
                }
                None => grop_clock::rt::current_policy(),
            };
            log::info!("pipeline: planner thread runs {policy}");
            let built = planner::feasibility::FcnEvaluator::load(&node_model)
                .map_err(|e| format!("loading {}: {e}", node_model.display()))
                .and_then(|psi| {
                    PlannerNode::new(
                        &node_ns,
                        node_scene,
                        robot,
                        Box::new(psi),
                        PlannerSettings::default(),
                        1,
                    )
                    .map_err(|e| format!("the planner node: {e}"))
                });
            let mut node = match built {
                Ok(node) => {
                    let _ = ready_tx.send(Ok(()));
                    node
                }
                Err(e) => {
                    let _ = ready_tx.send(Err(e.clone()));
                    return Err(e);
                }
            };
            node.run(&grop_clock::WallClock, &node_stop)
                .map_err(|e| e.to_string())?;
            Ok(())
        })
        .step("starting the planner node")?;
    match ready.recv_timeout(Duration::from_secs(60)) {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            return Err(BenchError::Setup {
                what: "the planner node".to_owned(),
                detail: e,
            });
        }
        Err(_) => {
            return Err(BenchError::Timeout {
                what: "the planner node's start".to_owned(),
                after: Duration::from_secs(60),
            });
        }
    }

    let mut to_plan: Vec<u64> = Vec::with_capacity(samples);
    let mut decision: Vec<u64> = Vec::with_capacity(samples);
    let result = (|| -> Result<(), BenchError> {
        for i in 0..samples as u64 + 3 {
            // Let the node settle into its wait between samples.
            std::thread::sleep(Duration::from_millis(15));
            let stamp = monotonic_ns();
            let frame_id = 1000 + i;
            let header = grop_ipc::CameraFrameHeader::for_layout(
                frame_id,
                stamp,
                &world::camera::FrameLayout::rgb8(camera),
            );
            frames
                .publish_with(|f| {
                    if let Ok(dst) = f.image_mut(header) {
                        dst.copy_from_slice(&image);
                    }
                })
                .step("publishing a frame")?;
            requests
                .publish_with(|r| {
                    r.request_id = i + 1;
                    r.stamp_ns = monotonic_ns();
                    r.reason = ReplanReason::MissionStart as u32;
                    r.remaining_mask = 0b111;
                    r.pose = [scene.loading_station.x_m, scene.loading_station.y_m, 0.0];
                })
                .step("publishing a request")?;
            let deadline = Instant::now() + Duration::from_secs(5);
            let plan = loop {
                let left = deadline.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    return Err(BenchError::Timeout {
                        what: format!("a plan for request {}", i + 1),
                        after: Duration::from_secs(5),
                    });
                }
                if let Some(p) = plans.recv_timeout(left).step("reading plans")? {
                    if p.answers_request == i + 1 {
                        break p;
                    }
                }
            };
            let held = monotonic_ns();
            if plan.source_frame_id != frame_id {
                return Err(BenchError::Peer(format!(
                    "plan {} used frame {}, not the new frame {frame_id}",
                    plan.plan_id, plan.source_frame_id
                )));
            }
            // The first samples warm caches and the model's buffers.
            if i >= 3 {
                to_plan.push(held.saturating_sub(stamp));
                decision.push(plan.decision_us.saturating_mul(1000));
            }
        }
        Ok(())
    })();
    stop.store(true, Ordering::Relaxed);
    let joined = planner.join();
    result?;
    match joined {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            return Err(BenchError::Setup {
                what: "the planner node".to_owned(),
                detail: e,
            });
        }
        Err(_) => {
            return Err(BenchError::Peer("the planner node panicked".to_owned()));
        }
    }
    Ok(PipelineResult {
        setting: rt.map_or_else(|| "no RT settings".to_owned(), |r| format!("`--rt {r}`")),
        frame_to_plan: Summary::of(&mut to_plan),
        decision: Summary::of(&mut decision),
    })
}

/// The markdown table of the pipeline section: one pair of rows per run, side by side, and
/// plan to motion.
pub fn markdown(runs: &[PipelineResult], plan_to_motion: &Summary) -> String {
    let row = |name: &str, setting: &str, s: &Summary| {
        format!(
            "| {name} | {setting} | {} | {:.0} | {:.0} | {:.0} |\n",
            s.count,
            s.p50_ns as f64 * 1e-3,
            s.p99_ns as f64 * 1e-3,
            s.max_ns as f64 * 1e-3
        )
    };
    let mut md = String::from(
        "Camera frame (640 x 480 RGB8, stamped at publish) to the plan held by a subscriber, \
         with a request published right behind the frame: `grop_onboard::planner_node` on the \
         wall clock, woken by the frame (`grop_ipc::wait_any`), cutting the views from the \
         frame, running Psi (tract) and GROP over the 288 plans of three objects, publishing \
         `plan/task`. The decision rows are the planner's own measurement of its work. The two \
         settings run one after the other in the same invocation. Target: frame to plan p99 \
         under 5 ms.\n\n\
         | path | planner thread | samples | p50 (us) | p99 (us) | max (us) |\n\
         |---|---|---|---|---|---|\n",
    );
    for r in runs {
        md += &row("frame stamp -> plan held", &r.setting, &r.frame_to_plan);
    }
    for r in runs {
        md += &row("decision (views + Psi + GROP)", &r.setting, &r.decision);
    }
    md += "\nPlan published to the first non-zero 0x500 motion frame on the CAN bus \
           (`latency::plan_motion`: the executive on the wall clock, the simulated base on an \
           in-process bus, an arm that finishes every skill at once, a new executive per \
           sample). The mission core runs every phase that is ready in one base cycle, and the \
           arm parks while the first plan is worked out, so what is left is the wait for the \
           base cycle that reads the plan (plans are read on base cycles), that cycle's path \
           request, and the next base cycle, which takes the path and commands the first \
           velocity: about two 20 ms base periods. Before the core (one phase per base cycle: \
           plan taken; arm parking started; arm parked; path requested; path taken; first \
           command) it was about six, 118 ms. In `grop demo` the arm's move to the carry pose \
           (about 2.8 s of simulated time) now overlaps the planning.\n\n\
           | path | samples | p50 (us) | p99 (us) | max (us) |\n|---|---|---|---|---|\n";
    md += &format!(
        "| plan published -> first motion frame on CAN | {} | {:.0} | {:.0} | {:.0} |\n",
        plan_to_motion.count,
        plan_to_motion.p50_ns as f64 * 1e-3,
        plan_to_motion.p99_ns as f64 * 1e-3,
        plan_to_motion.max_ns as f64 * 1e-3
    );
    md
}
