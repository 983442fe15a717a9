//! The planner node in-process: a rendered camera frame and replan requests go in over iceoryx2
//! (unique namespace per test), the task plan, heatmaps and heartbeats come out.
#![allow(
    clippy::too_many_lines,
    reason = "a test scenario (or the fuzz harness's) reads top to bottom as one story"
)]
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use grop_ipc::{
    CameraFrameMsg, HeartbeatMsg, HeatmapsMsg, IpcNode, ProcessRole, ReplanReason,
    ReplanRequestMsg, TaskPlanMsg, TaskStep, TaskStepKind, TopicPublisher, TopicSubscriber,
};
use grop_onboard::deployment::{PlannerSettings, RetryPolicy};
use grop_onboard::planner_node::{Answer, PlannerNode};
use planner::costs::GridTravelTime;
use planner::feasibility::FcnEvaluator;
use planner::methods::{MethodKind, Planner, PlannerConfig, TaskMotionPlanner};
use planner::problem::TaskProblem;
use world::camera::{FrameLayout, OverheadCamera, render_frame};
use world::{RobotConfig, Scene, Side};

static COUNTER: AtomicU32 = AtomicU32::new(0);

/// A namespace no other test uses: pid + counter + test name.
fn unique_namespace(test: &str) -> String {
    format!(
        "test-{}-{}-{test}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

fn psi() -> FcnEvaluator {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../models/psi-fcn.onnx");
    FcnEvaluator::load(&path).unwrap()
}

/// The other side of the node: camera, executive.
struct Peers {
    _node: IpcNode,
    camera: TopicPublisher<CameraFrameMsg>,
    requests: TopicPublisher<ReplanRequestMsg>,
    plans: TopicSubscriber<TaskPlanMsg>,
    heatmaps: TopicSubscriber<HeatmapsMsg>,
    health: TopicSubscriber<HeartbeatMsg>,
    events: TopicSubscriber<grop_ipc::EventMsg>,
}

fn peers(namespace: &str) -> Peers {
    let node = IpcNode::new(namespace, "peers").unwrap();
    Peers {
        camera: node.publisher().unwrap(),
        requests: node.publisher().unwrap(),
        plans: node.subscriber().unwrap(),
        heatmaps: node.subscriber().unwrap(),
        health: node.subscriber().unwrap(),
        events: node.subscriber().unwrap(),
        _node: node,
    }
}

fn publish_frame(camera: &TopicPublisher<CameraFrameMsg>, scene: &Scene, frame_id: u64) {
    publish_frame_at(camera, scene, frame_id, Duration::from_nanos(1));
}

fn publish_frame_at(
    camera: &TopicPublisher<CameraFrameMsg>,
    scene: &Scene,
    frame_id: u64,
    stamp: Duration,
) {
    let cam = OverheadCamera::fitting_room(scene);
    let header = grop_ipc::CameraFrameHeader::for_layout(
        frame_id,
        u64::try_from(stamp.as_nanos()).unwrap(),
        &FrameLayout::rgb8(cam),
    );
    camera
        .publish_with(|frame| {
            let pixels = frame.image_mut(header).unwrap();
            render_frame(scene, &cam, pixels).unwrap();
        })
        .unwrap();
}

fn request(id: u64, reason: ReplanReason, pose: [f64; 3], remaining: u64) -> ReplanRequestMsg {
    let mut r = ReplanRequestMsg {
        request_id: id,
        stamp_ns: 0,
        reason: 0,
        failed_object: 0,
        remaining_mask: remaining,
        on_board_mask: 0,
        pose,
        failed_side: 0,
        flags: 0,
        tray: [0; grop_ipc::MAX_TRAY_SLOTS],
        failed_goal_m: [0.0; 2],
    };
    r.set_reason(reason);
    r
}

/// A request's tray holding the objects of `mask` in the first slots, in object order (as
/// the executive loads them when the plan says so).
fn tray_holding(mask: u64) -> [u8; grop_ipc::MAX_TRAY_SLOTS] {
    let mut tray = [0; grop_ipc::MAX_TRAY_SLOTS];
    let objects = (0..64u8).filter(|o| mask & (1u64 << o) != 0);
    for (slot, object) in tray.iter_mut().zip(objects) {
        *slot = object + 1;
    }
    tray
}

/// Steps the node (10 ms of clock time per step) until it answers.
fn step_until_answer(node: &mut PlannerNode, now: &mut Duration) -> Answer {
    for _ in 0..200 {
        *now += Duration::from_millis(10);
        if let Some(answer) = node.step(*now).unwrap() {
            return answer;
        }
    }
    panic!("no answer; failures {:?}", node.failures());
}

fn newest<T: grop_ipc::Topic + Copy>(sub: &TopicSubscriber<T>) -> T {
    for _ in 0..100 {
        if let Some(m) = sub.latest().unwrap() {
            return *m;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    panic!("nothing on {}", sub.service());
}

fn kinds(steps: &[TaskStep]) -> Vec<TaskStepKind> {
    steps.iter().map(|s| s.kind().unwrap()).collect()
}

/// (object, side) of each unload, in order.
fn unloads(steps: &[TaskStep]) -> Vec<(usize, Side)> {
    steps
        .iter()
        .filter(|s| s.kind() == Ok(TaskStepKind::Unload))
        .map(|s| {
            let side = if s.side == 1 { Side::Near } else { Side::Far };
            (s.object().unwrap(), side)
        })
        .collect()
}

fn start_pose(scene: &Scene) -> [f64; 3] {
    [
        scene.robot_start.x_m,
        scene.robot_start.y_m,
        scene.robot_start.yaw_rad,
    ]
}

/// A mission start: the plan's structure, its F against the heatmaps, and the same choice as
/// `Planner::plan` on `TaskProblem::from_world` (rendered crops) for several scenes and seeds.
#[test]
fn mission_start_plans_like_the_offline_planner() {
    let robot = RobotConfig::default();
    let mut offline_psi = psi();
    let mut same_plans = 0;
    let cases = [(1u64, 7u64), (2, 11), (3, 42), (4, 5), (5, 99)];
    for &(scene_seed, seed) in &cases {
        let scene = world::generate::evaluation_scene(scene_seed, 20, 3);
        let ns = unique_namespace("mission");
        let settings = PlannerSettings::default();
        let mut node = PlannerNode::new(
            &ns,
            scene.clone(),
            robot.clone(),
            Box::new(psi()),
            settings,
            seed,
        )
        .unwrap();
        let p = peers(&ns);
        publish_frame(&p.camera, &scene, 17);
        p.requests
            .publish(&request(
                1,
                ReplanReason::MissionStart,
                start_pose(&scene),
                0b111,
            ))
            .unwrap();
        let mut now = Duration::from_secs(1);
        let answer = step_until_answer(&mut node, &mut now);
        assert!(answer.replanned);
        let plan = newest(&p.plans);
        let heatmaps = newest(&p.heatmaps);
        assert_eq!(plan.answers_request, 1);
        assert_eq!(plan.plan_id, answer.plan_id);
        assert_eq!(plan.source_frame_id, 17);
        assert_eq!(heatmaps.source_frame_id, 17);
        assert_eq!(plan.object_count, 3);
        let steps = plan.steps().unwrap();
        use TaskStepKind::{Load, Navigate, Unload};
        assert_eq!(
            kinds(steps),
            [
                Navigate, Load, Navigate, Unload, Navigate, Unload, Navigate, Unload
            ]
        );
        assert_eq!(steps[1].load_mask, 0b111);
        assert_eq!(
            (steps[0].x_m, steps[0].y_m),
            (scene.loading_station.x_m, scene.loading_station.y_m)
        );
        let locations = heatmaps.locations().unwrap();
        assert_eq!(locations.len(), 6);
        let mut f_sum = 0.0;
        for pair in steps[2..].chunks(2) {
            let (nav, unload) = (pair[0], pair[1]);
            assert_eq!(nav.side, unload.side);
            assert_eq!(
                (nav.x_m, nav.y_m, nav.yaw_rad),
                (unload.x_m, unload.y_m, unload.yaw_rad)
            );
            assert!(nav.travel_cost_s > 0.0);
            let h = locations
                .iter()
                .find(|h| h.object_index == unload.object_index && h.side == unload.side)
                .unwrap();
            assert_eq!(
                h.feasibility, unload.feasibility,
                "F of the unload = F of its heatmap"
            );
            assert_eq!(h.target_m, unload.target_m);
            f_sum += unload.feasibility;
        }
        assert!((plan.feasibility - f_sum).abs() < 1e-9);
        assert!((plan.utility - (plan.reward * plan.feasibility - plan.cost_s)).abs() < 1e-6);
        let legs: f64 = steps.iter().map(|s| s.travel_cost_s).sum();
        assert!(
            (legs - plan.cost_s).abs() < 1e-6,
            "legs {legs} vs C {}",
            plan.cost_s
        );

        // Offline: rendered crops, the map's start, same seed.
        let targets: Vec<[f64; 3]> = scene.targets.iter().map(|t| t.as_array()).collect();
        let problem = TaskProblem::from_world(&scene, &robot, &targets, &mut offline_psi).unwrap();
        let grid = world::nav::OccupancyGrid::from_scene(&scene, &robot);
        let mut travel = GridTravelTime::new(&grid, robot.speed_mps);
        let mut grop = Planner::new(MethodKind::Grop, PlannerConfig::for_robot(&robot));
        let offline = grop.plan(&problem, &mut travel, seed).unwrap();
        let offline_unloads: Vec<(usize, Side)> = offline
            .plan
            .unloads
            .iter()
            .map(|u| (u.object, u.side))
            .collect();
        println!(
            "scene {scene_seed} seed {seed}: node {:?} F {:.4} U {:.2} ({} us) | offline {:?} F {:.4} U {:.2}",
            unloads(steps),
            plan.feasibility,
            plan.utility,
            plan.decision_us,
            offline_unloads,
            offline.feasibility,
            offline.utility
        );
        assert!((plan.feasibility - offline.feasibility).abs() < 0.1);
        if unloads(steps) == offline_unloads {
            same_plans += 1;
        }
    }
    // Cut and rendered crops differ by a fraction of a gray level (mean |dF| ~ 0.001); a Smp goal
    // may land on a neighbouring cell, but the task plan should be the same.
    assert!(
        same_plans >= cases.len() - 1,
        "{same_plans} of {} plans equal",
        cases.len()
    );
}

/// A failed unload, paper policy (no retry): the rest of the current plan without the failed
/// object, no station visit (everything is on board), same goals; then with `replan`: a fresh
/// plan from the pose over what is left, the failed object included, no station visit.
#[test]
fn failed_unloads_are_answered_by_retry_policy() {
    let robot = RobotConfig::default();
    let scene = world::generate::evaluation_scene(8, 20, 3);
    for retry in [RetryPolicy::None, RetryPolicy::Replan] {
        let ns = unique_namespace("retry");
        let settings = PlannerSettings {
            retry,
            ..PlannerSettings::default()
        };
        let mut node = PlannerNode::new(
            &ns,
            scene.clone(),
            robot.clone(),
            Box::new(psi()),
            settings,
            3,
        )
        .unwrap();
        let p = peers(&ns);
        publish_frame(&p.camera, &scene, 1);
        p.requests
            .publish(&request(
                1,
                ReplanReason::MissionStart,
                start_pose(&scene),
                0b111,
            ))
            .unwrap();
        let mut now = Duration::from_secs(1);
        step_until_answer(&mut node, &mut now);
        let first = newest(&p.plans);
        let first_steps = first.steps().unwrap().to_vec();
        let order = unloads(&first_steps);
        // The first unload fails where the robot stands.
        let failed = first_steps[3];
        let mut failure = request(
            2,
            ReplanReason::UnloadFailed,
            [failed.x_m, failed.y_m, failed.yaw_rad],
            0b111,
        );
        failure.failed_object = failed.object_index;
        failure.failed_side = failed.side;
        failure.on_board_mask = 0b111;
        failure.tray = tray_holding(failure.on_board_mask);
        // At the table, as the executive says after an unload.
        failure.flags = grop_ipc::REQUEST_AT_TABLE;
        p.requests.publish(&failure).unwrap();
        let answer = step_until_answer(&mut node, &mut now);
        let plan = newest(&p.plans);
        assert_eq!(plan.answers_request, 2);
        let steps = plan.steps().unwrap();
        assert!(
            steps.iter().all(|s| s.kind() != Ok(TaskStepKind::Load)),
            "everything is on board: no station visit"
        );
        match retry {
            RetryPolicy::None => {
                assert!(!answer.replanned);
                assert_eq!(unloads(steps), order[1..].to_vec());
                assert_eq!(steps, &first_steps[4..]);
            }
            RetryPolicy::Replan => {
                assert!(answer.replanned);
                let mut objects: Vec<usize> = unloads(steps).iter().map(|u| u.0).collect();
                objects.sort_unstable();
                assert_eq!(objects, [0, 1, 2], "the failed object is tried again");
            }
            RetryPolicy::GropPlus => {
                unreachable!("failed_unload_is_answered_with_the_grop_plus_retry")
            }
        }
        // Legs are costed from the pose.
        assert!(steps[0].travel_cost_s > 0.0);
    }
}

/// The steps with the first leg's cost zeroed (it is costed from wherever the robot stands).
fn without_first_leg_cost(steps: &[TaskStep]) -> Vec<TaskStep> {
    let mut v = steps.to_vec();
    v[0].travel_cost_s = 0.0;
    v
}

/// A failed unload with `retry = "grop-plus"`: the node answers with GROP+'s retry
/// (`planner::grop_plus::retry_goal` on the problem it planned with) first, then the rest of the
/// current plan; once the object's retries are spent, it drops the object like the paper.
#[test]
fn failed_unload_is_answered_with_the_grop_plus_retry() {
    let robot = RobotConfig::default();
    let scene = world::generate::evaluation_scene(8, 20, 3);
    let ns = unique_namespace("grop-plus");
    let settings = PlannerSettings {
        retry: RetryPolicy::GropPlus,
        ..PlannerSettings::default()
    };
    let mut node = PlannerNode::new(
        &ns,
        scene.clone(),
        robot.clone(),
        Box::new(psi()),
        settings,
        3,
    )
    .unwrap();
    let config = node.planner_config();
    let max_retries = config.plus.max_retries;
    assert!(max_retries >= 1, "GROP+'s default retries");
    let p = peers(&ns);
    publish_frame(&p.camera, &scene, 1);
    p.requests
        .publish(&request(
            1,
            ReplanReason::MissionStart,
            start_pose(&scene),
            0b111,
        ))
        .unwrap();
    let mut now = Duration::from_secs(1);
    step_until_answer(&mut node, &mut now);
    let first_steps = newest(&p.plans).steps().unwrap().to_vec();
    let order = unloads(&first_steps);
    let object = order[0].0;
    let grid = world::nav::OccupancyGrid::from_scene(&scene, &robot);

    let mut failed = first_steps[3];
    let mut tried: Vec<(f64, f64)> = Vec::new();
    for (request_id, retry) in (2u64..).zip(0..=max_retries) {
        let pose = [failed.x_m + 0.03, failed.y_m - 0.02, failed.yaw_rad];
        let mut failure = request(request_id, ReplanReason::UnloadFailed, pose, 0b111);
        failure.failed_object = failed.object_index;
        failure.failed_side = failed.side;
        failure.failed_goal_m = [failed.x_m, failed.y_m];
        failure.on_board_mask = 0b111;
        failure.tray = tray_holding(failure.on_board_mask);
        // At the table, as the executive says after an unload.
        failure.flags = grop_ipc::REQUEST_AT_TABLE;
        tried.push((failed.x_m, failed.y_m));
        p.requests.publish(&failure).unwrap();
        let answer = step_until_answer(&mut node, &mut now);
        assert!(!answer.replanned, "no new frame or Psi run for a retry");
        let plan = newest(&p.plans);
        assert_eq!(plan.answers_request, request_id);
        let steps = plan.steps().unwrap();
        assert!(steps.iter().all(|s| s.kind() != Ok(TaskStepKind::Load)));

        // What the policy says on the node's own problem.
        let (objects, problem) = node.last_problem().unwrap();
        let local = objects.iter().position(|&o| o == object).unwrap();
        let mut travel = GridTravelTime::new(&grid, robot.speed_mps);
        let expected = planner::grop_plus::retry_goal(
            &config,
            problem,
            local,
            &tried,
            (pose[0], pose[1]),
            retry,
            &mut travel,
        );
        match expected {
            Some(goal) if retry < max_retries => {
                let side = problem.locations[goal.location].side;
                assert_eq!(
                    unloads(steps)[0],
                    (object, side),
                    "retry {retry}: the failed object first"
                );
                let (nav, unload) = (steps[0], steps[1]);
                assert_eq!(
                    (nav.x_m, nav.y_m, nav.yaw_rad),
                    (goal.xy.0, goal.xy.1, goal.yaw_rad)
                );
                assert_eq!((unload.x_m, unload.y_m), goal.xy);
                assert!(!tried.contains(&goal.xy), "a tried goal is not repeated");
                assert!(nav.travel_cost_s >= 0.0);
                // Then the rest of the plan, as it was.
                assert_eq!(unloads(&steps[2..]), order[1..].to_vec());
                assert_eq!(
                    without_first_leg_cost(&steps[2..]),
                    without_first_leg_cost(&first_steps[4..])
                );
                failed = unload;
            }
            _ => {
                assert_eq!(
                    retry, max_retries,
                    "the policy retries while its budget lasts"
                );
                // Given up: the paper's answer without the object.
                assert_eq!(unloads(steps), order[1..].to_vec());
                assert_eq!(
                    without_first_leg_cost(steps),
                    without_first_leg_cost(&first_steps[4..])
                );
                return;
            }
        }
    }
    panic!("the retry budget was never spent");
}

/// The loop on a simulated clock: one heartbeat per 100 ms of clock time, role Planner.
#[test]
fn heartbeats_every_100_ms_of_clock_time() {
    let scene = world::generate::evaluation_scene(9, 15, 2);
    let ns = unique_namespace("heartbeat");
    let mut node = PlannerNode::new(
        &ns,
        scene,
        RobotConfig::default(),
        Box::new(psi()),
        PlannerSettings::default(),
        0,
    )
    .unwrap();
    let p = peers(&ns);
    // Time moves only by the loop's sleeps; the flag stops the loop at 5.995 s.
    let (clock, stop) = grop_clock::ManualClock::until(Duration::from_millis(5_995));
    clock.set(Duration::from_secs(5));
    node.run(&clock, &stop).unwrap();
    let mut beats = Vec::new();
    while let Some(b) = p.health.try_recv().unwrap() {
        beats.push(*b);
    }
    assert_eq!(beats.len(), 10, "{beats:?}");
    for (i, b) in beats.iter().enumerate() {
        assert_eq!(b.role(), Ok(ProcessRole::Planner));
        assert_eq!(b.seq, i as u64 + 1);
        assert_eq!(b.stamp_ns, 5_000_000_000 + 100_000_000 * i as u64);
        assert_eq!(b.pid, std::process::id());
    }
    assert_eq!(node.overruns(), 0);
}

/// Asks for a mission-start plan (request 1) and checks that five 10 ms steps give none.
fn ask_and_expect_no_plan(
    node: &mut PlannerNode,
    p: &Peers,
    scene: &Scene,
    now: &mut Duration,
    why: &str,
) {
    p.requests
        .publish(&request(
            1,
            ReplanReason::MissionStart,
            start_pose(scene),
            0,
        ))
        .unwrap();
    for _ in 0..5 {
        *now += Duration::from_millis(10);
        assert_eq!(node.step(*now).unwrap(), None, "{why}");
    }
}

/// A node on `scene` with Psi, the default robot and settings, as most tests want it.
fn default_node(ns: &str, scene: &Scene) -> PlannerNode {
    PlannerNode::new(
        ns,
        scene.clone(),
        RobotConfig::default(),
        Box::new(psi()),
        PlannerSettings::default(),
        0,
    )
    .unwrap()
}

/// A request before any frame waits for the frame; a frame whose header does not cover the
/// targets is an error the node survives.
#[test]
fn requests_wait_for_a_frame_and_bad_frames_are_survived() {
    let scene = world::generate::evaluation_scene(10, 20, 2);
    let ns = unique_namespace("noframe");
    let mut node = default_node(&ns, &scene);
    let p = peers(&ns);
    p.requests
        .publish(&request(
            1,
            ReplanReason::MissionStart,
            start_pose(&scene),
            0,
        ))
        .unwrap();
    let mut now = Duration::ZERO;
    for _ in 0..5 {
        now += Duration::from_millis(10);
        assert_eq!(node.step(now).unwrap(), None);
    }
    // A frame that sees only the room's west end.
    let cam = OverheadCamera::fitting_room(&scene);
    let west = OverheadCamera {
        width_px: 100,
        ..cam
    };
    let header = grop_ipc::CameraFrameHeader::for_layout(3, 0, &FrameLayout::rgb8(west));
    p.camera
        .publish_with(|f| {
            f.image_mut(header).unwrap().fill(96);
        })
        .unwrap();
    // Views past its edge inside the room are unknown: the objects whose views keep no goal
    // are reported on `events` and left out; the rest (if any) are planned.
    let answer = step_until_answer(&mut node, &mut now);
    assert_eq!(answer.request_id, 1);
    assert_eq!(node.failures().0, 0);
    let mut not_planned = Vec::new();
    for _ in 0..50 {
        while let Some(e) = p.events.try_recv().unwrap() {
            if e.kind() == Ok(grop_ipc::EventKind::NotPlanned) {
                not_planned.push(e.detail().unwrap().to_owned());
            }
        }
        if !not_planned.is_empty() {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let plan = newest(&p.plans);
    let planned = unloads(plan.steps().unwrap()).len();
    assert_eq!(
        planned + not_planned.len(),
        scene.targets.len(),
        "{not_planned:?}"
    );
    assert!(
        !not_planned.is_empty(),
        "a frame of the west end sees no target"
    );
    for d in &not_planned {
        assert!(d.contains("not planned") && d.contains("unknown"), "{d}");
    }
    for t in &scene.targets {
        // Only targets whose views lie wholly east of the frame's edge go unplanned.
        let edge = cam.left_x_m + 100.0 * cam.metres_per_px;
        if t.x_m - 2.0 < edge {
            assert!(planned > 0, "the target at x {} is partly seen", t.x_m);
        }
    }
    // The right frame and a new request: answered, all targets (mask 0 at mission start).
    publish_frame(&p.camera, &scene, 4);
    p.requests
        .publish(&request(
            2,
            ReplanReason::MissionStart,
            start_pose(&scene),
            0,
        ))
        .unwrap();
    let answer = step_until_answer(&mut node, &mut now);
    assert_eq!(answer.request_id, 2);
    assert_eq!(answer.step_count, 2 + 2 * scene.targets.len());
}

/// A frozen camera (its last frame delivered again and again, stamped when it was taken): no
/// plan from a frame older than MAX_FRAME_AGE; the request waits, and a fresh frame answers it.
#[test]
fn a_frozen_camera_frame_is_not_planned_from() {
    let scene = world::generate::evaluation_scene(10, 20, 2);
    let ns = unique_namespace("frozen");
    let mut node = default_node(&ns, &scene);
    let p = peers(&ns);
    // Frame 1, stamped at 0; the camera then freezes.
    publish_frame(&p.camera, &scene, 1);
    let mut now = grop_onboard::planner_node::MAX_FRAME_AGE + Duration::from_secs(7);
    ask_and_expect_no_plan(
        &mut node,
        &p,
        &scene,
        &mut now,
        "planned from a 10 s old frame",
    );
    let (failures, last) = node.failures();
    assert_eq!(failures, 1, "reported once");
    assert!(last.unwrap().contains("s old"), "{last:?}");
    // The same frozen frame again: still nothing.
    publish_frame(&p.camera, &scene, 1);
    now += Duration::from_millis(10);
    assert_eq!(node.step(now).unwrap(), None);
    // A fresh frame: the waiting request is answered.
    publish_frame_at(&p.camera, &scene, 2, now);
    let answer = step_until_answer(&mut node, &mut now);
    assert_eq!(answer.request_id, 1);
}

#[test]
fn a_camera_frame_stamped_in_the_future_is_refused_and_a_frame_goes_stale_from_its_arrival() {
    let scene = world::generate::evaluation_scene(10, 20, 2);
    let ns = unique_namespace("future");
    let mut node = default_node(&ns, &scene);
    let p = peers(&ns);
    let mut now = Duration::from_secs(5);
    // Stamped 1 h ahead: before, its age read 0 s for an hour, so a camera frozen on it
    // would be planned from all that time.
    publish_frame_at(&p.camera, &scene, 1, now + Duration::from_secs(3600));
    ask_and_expect_no_plan(
        &mut node,
        &p,
        &scene,
        &mut now,
        "planned from a frame stamped in the future",
    );
    assert_eq!(node.frames_refused(), 1);
    let (_, last) = node.failures();
    assert!(last.unwrap().contains("in the future"), "{last:?}");
    // A frame stamped now is planned from ...
    publish_frame_at(&p.camera, &scene, 2, now);
    let answer = step_until_answer(&mut node, &mut now);
    assert_eq!(answer.request_id, 1);
    // ... and, once the camera stops, goes stale MAX_FRAME_AGE after it arrived, even if its
    // stamp (just inside the lead allowed) would keep it fresh a little longer.
    publish_frame_at(&p.camera, &scene, 3, now + Duration::from_millis(90));
    now += Duration::from_millis(10);
    node.step(now).unwrap();
    now += grop_onboard::planner_node::MAX_FRAME_AGE + Duration::from_millis(50);
    p.requests
        .publish(&request(
            2,
            ReplanReason::MissionStart,
            start_pose(&scene),
            0,
        ))
        .unwrap();
    assert_eq!(node.step(now).unwrap(), None, "planned from a stale frame");
}

/// Objects of the unloads in `steps`, as a bit set.
fn unload_mask(steps: &[TaskStep]) -> u64 {
    steps
        .iter()
        .filter(|s| s.kind() == Ok(TaskStepKind::Unload))
        .fold(0, |m, s| m | (1u64 << s.object().unwrap()))
}

/// Checks a multi-trip plan's shape against the tray: every step decodes; every station visit
/// (navigate to the station, load) loads objects none of which is on board (`on_board`: the tray
/// at the start) and never more than `capacity` on the tray; at a station visit the tray holds
/// only objects the plan never unloads (given up); every unload is of an object on board, at most
/// once; C is the sum of the legs and F the sum of the unloads'. Returns the load masks in order.
fn check_trips(plan: &TaskPlanMsg, scene: &Scene, capacity: usize, mut on_board: u64) -> Vec<u64> {
    let steps = plan.steps().unwrap();
    for s in steps {
        s.kind().unwrap();
    }
    let station = (scene.loading_station.x_m, scene.loading_station.y_m);
    let mut loads = Vec::new();
    let mut unloaded = 0u64;
    let mut at_visits = 0u64;
    let mut i = 0;
    while i < steps.len() {
        if steps[i].kind() == Ok(TaskStepKind::Load) {
            panic!("a load step without a navigation to the station before it");
        }
        if i + 1 < steps.len() && steps[i + 1].kind() == Ok(TaskStepKind::Load) {
            assert_eq!(steps[i].kind(), Ok(TaskStepKind::Navigate));
            assert_eq!((steps[i].x_m, steps[i].y_m), station);
            let mask = steps[i + 1].load_mask;
            assert_ne!(mask, 0);
            assert_eq!(on_board & mask, 0);
            at_visits |= on_board;
            on_board |= mask;
            assert!(on_board.count_ones() as usize <= capacity, "{on_board:#x}");
            loads.push(mask);
            i += 2;
            continue;
        }
        let (nav, unload) = (steps[i], steps[i + 1]);
        assert_eq!(nav.kind(), Ok(TaskStepKind::Navigate));
        assert_eq!(unload.kind(), Ok(TaskStepKind::Unload));
        assert_eq!(nav.side, unload.side);
        assert_eq!(
            (nav.x_m, nav.y_m, nav.yaw_rad),
            (unload.x_m, unload.y_m, unload.yaw_rad)
        );
        let bit = 1u64 << unload.object().unwrap();
        assert_ne!(
            on_board & bit,
            0,
            "object {} is not on board",
            unload.object_index
        );
        assert_eq!(unloaded & bit, 0, "object {} twice", unload.object_index);
        on_board &= !bit;
        unloaded |= bit;
        i += 2;
    }
    assert_eq!(
        at_visits & unloaded,
        0,
        "only objects given up stay on the tray at a station visit"
    );
    let legs: f64 = steps.iter().map(|s| s.travel_cost_s).sum();
    assert!(
        (legs - plan.cost_s).abs() < 1e-6,
        "legs {legs} vs C {}",
        plan.cost_s
    );
    let f: f64 = steps
        .iter()
        .filter(|s| s.kind() == Ok(TaskStepKind::Unload))
        .map(|s| s.feasibility)
        .sum();
    assert!((f - plan.feasibility).abs() < 1e-9);
    assert!((plan.utility - (plan.reward * plan.feasibility - plan.cost_s)).abs() < 1e-6);
    loads
}

/// Six objects with the default tray of 3: one plan message of two trips (station, load 3,
/// 3 x (navigate, unload)), exactly the multi-trip planner's trips on the node's own problem;
/// then a failed unload in the first trip, answered by each retry policy over both trips: the
/// objects on board are delivered first, then one station visit for the second trip's objects.
#[test]
fn six_objects_with_a_tray_of_three_are_planned_as_two_trips() {
    use TaskStepKind::{Load, Navigate, Unload};
    let robot = RobotConfig::default();
    assert_eq!(robot.carry_capacity, 3);
    let scene = world::generate::evaluation_scene(4, 20, 6);
    let all = 0b11_1111u64;
    for retry in [
        RetryPolicy::None,
        RetryPolicy::Replan,
        RetryPolicy::GropPlus,
    ] {
        let ns = unique_namespace("trips");
        let settings = PlannerSettings {
            retry,
            ..PlannerSettings::default()
        };
        let mut node = PlannerNode::new(
            &ns,
            scene.clone(),
            robot.clone(),
            Box::new(psi()),
            settings,
            5,
        )
        .unwrap();
        let p = peers(&ns);
        publish_frame(&p.camera, &scene, 3);
        p.requests
            .publish(&request(
                1,
                ReplanReason::MissionStart,
                start_pose(&scene),
                0,
            ))
            .unwrap();
        let mut now = Duration::from_secs(1);
        let answer = step_until_answer(&mut node, &mut now);
        assert!(answer.replanned);
        let plan = newest(&p.plans);
        assert_eq!(plan.object_count, 6);
        let steps = plan.steps().unwrap().to_vec();
        let trip = [
            Navigate, Load, Navigate, Unload, Navigate, Unload, Navigate, Unload,
        ];
        assert_eq!(kinds(&steps), [trip, trip].concat());
        let loads = check_trips(&plan, &scene, 3, 0);
        assert_eq!(loads.len(), 2);
        assert_eq!(loads[0] | loads[1], all);
        assert_eq!(loads[0] & loads[1], 0);
        assert_eq!(unload_mask(&steps), all);
        assert_eq!(newest(&p.heatmaps).locations().unwrap().len(), 12);

        // The node's trips are the multi-trip planner's on the node's problem.
        let (objects, problem) = node.last_problem().unwrap();
        let grid = world::nav::OccupancyGrid::from_scene(&scene, &robot);
        let mut travel = GridTravelTime::new(&grid, robot.speed_mps);
        let offline = planner::trip_methods::MultiTripPlanner::new(
            MethodKind::GropPlus,
            node.planner_config(),
            3,
        )
        .plan(problem, &mut travel, 5)
        .unwrap();
        let offline_unloads: Vec<(usize, Side)> = offline
            .plan
            .unloads()
            .map(|u| (objects[u.object], u.side))
            .collect();
        assert_eq!(unloads(&steps), offline_unloads);

        // The first unload fails: trip 1's three objects are on board.
        let failed = steps[3];
        let mut failure = request(
            2,
            ReplanReason::UnloadFailed,
            [failed.x_m, failed.y_m, failed.yaw_rad],
            all,
        );
        failure.failed_object = failed.object_index;
        failure.failed_side = failed.side;
        failure.failed_goal_m = [failed.x_m, failed.y_m];
        failure.on_board_mask = loads[0];
        failure.tray = tray_holding(failure.on_board_mask);
        p.requests.publish(&failure).unwrap();
        let answer = step_until_answer(&mut node, &mut now);
        let plan = newest(&p.plans);
        assert_eq!(plan.answers_request, 2);
        let after = plan.steps().unwrap();
        let failed_bit = 1u64 << failed.object_index;
        let second = check_trips(&plan, &scene, 3, loads[0]);
        if unload_mask(after) & failed_bit != 0 {
            assert_eq!(
                second,
                [loads[1]],
                "one station visit, for trip 2's objects"
            );
        } else {
            // The object given up keeps its slot: trip 2 takes two station visits.
            assert_eq!(second.len(), 2, "{second:x?}");
            assert_eq!(second[0] | second[1], loads[1]);
        }
        match retry {
            RetryPolicy::None => {
                assert!(!answer.replanned);
                assert_eq!(unload_mask(after), all & !failed_bit);
                // Same goals, same order as the first plan without the failed object.
                let expected: Vec<(usize, Side)> = unloads(&steps)[1..].to_vec();
                assert_eq!(unloads(after), expected);
            }
            RetryPolicy::Replan => {
                assert!(answer.replanned);
                assert_eq!(unload_mask(after), all, "the failed object is tried again");
            }
            RetryPolicy::GropPlus => {
                assert!(!answer.replanned);
                let first = unloads(after)[0].0;
                if unload_mask(after) == all {
                    assert_eq!(first, failed.object_index as usize, "the retry comes first");
                } else {
                    assert_eq!(unload_mask(after), all & !failed_bit);
                }
            }
        }
    }
}

/// The largest tasks: 12 place settings (36 objects) with a tray of 3 are 12 trips of
/// 2 + 2 x 3 steps = 96 steps; a tray of 1 makes 4 steps per object, so 32 objects fill the
/// message's 128 steps exactly and 33 do not fit: that request is refused with a clear error,
/// the node goes on.
#[test]
fn largest_tasks_fit_the_plan_message_and_larger_are_refused() {
    let cases: [(usize, u32, u64, Option<usize>); 3] = [
        (12, 3, 0, Some(96)),
        (11, 1, (1u64 << 32) - 1, Some(128)),
        (11, 1, 0, None),
    ];
    for (settings_count, capacity, remaining, expected_steps) in cases {
        let scene = world::table_settings::table_settings_scene(2, settings_count).unwrap();
        let robot = RobotConfig {
            carry_capacity: capacity,
            ..RobotConfig::default()
        };
        let ns = unique_namespace("largest");
        let mut node = PlannerNode::new(
            &ns,
            scene.clone(),
            robot,
            Box::new(psi()),
            PlannerSettings::default(),
            9,
        )
        .unwrap();
        let p = peers(&ns);
        publish_frame(&p.camera, &scene, 1);
        p.requests
            .publish(&request(
                1,
                ReplanReason::MissionStart,
                start_pose(&scene),
                remaining,
            ))
            .unwrap();
        let mut now = Duration::from_secs(1);
        match expected_steps {
            Some(count) => {
                let answer = step_until_answer(&mut node, &mut now);
                assert_eq!(answer.step_count, count);
                let plan = newest(&p.plans);
                let loads = check_trips(&plan, &scene, capacity as usize, 0);
                let n = if remaining == 0 {
                    scene.targets.len()
                } else {
                    remaining.count_ones() as usize
                };
                assert_eq!(loads.len(), n.div_ceil(capacity as usize));
                assert_eq!(unload_mask(plan.steps().unwrap()).count_ones() as usize, n);
                println!(
                    "{n} objects, tray {capacity}: {count} steps, decision {} us",
                    plan.decision_us
                );
            }
            None => {
                for _ in 0..20 {
                    now += Duration::from_millis(10);
                    assert_eq!(node.step(now).unwrap(), None);
                }
                let (failures, why) = node.failures();
                assert_eq!(failures, 1);
                let why = why.unwrap();
                assert!(why.contains("steps") && why.contains("128"), "{why}");
            }
        }
    }
}
