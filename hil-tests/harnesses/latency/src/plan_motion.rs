//! Plan to the first motion frame on the CAN bus, on the wall clock: the executive
//! (`grop_onboard::executive`, the code `grop-executive` runs) with the simulated base on an
//! in-process CAN bus and an arm that is already parked (every skill done at once, so no arm
//! motion is timed), fed exact localisation fixes and planner heartbeats. When the mission has
//! started and asked for its plan, the plan (one leg of 1.2 m straight ahead, then an unload) is
//! published; the time to the first 0x500 frame with a non-zero command is taken where that
//! frame appears on the bus. It is the executive's reaction: the plan read in a 2 ms cycle, the
//! path from its worker thread, the next 50 Hz base cycle's command.

use std::sync::Arc;
use std::time::Duration;

use can_bus::{CanBus, CanId, MemoryBus};
use grop_clock::Clock;
use grop_ipc::{
    BasePoseMsg, HeartbeatMsg, IpcNode, PoseFixKind, ProcessRole, ReplanRequestMsg, TableSide,
    TaskPlanMsg, TaskStep,
};
use grop_onboard::executive::unload::{ArmFault, ArmPort, SkillStatus};
use grop_onboard::executive::{ArmDevice, ArmSnapshot, Executive, ExecutiveConfig, MissionState};
use sim_rmp::{SimConfig, SimRmp, SimRmpNode};
use ur5e_kin::Joints;

use crate::stats::Summary;
use crate::{BenchError, Step};
use grop_clock::duration_ns as ns;

/// An arm that is parked and answers every skill as done at once.
struct ParkedArm;

impl ArmPort for ParkedArm {
    fn start_move_joints(&mut self, _q: &Joints, _now: Duration) -> Result<(), ArmFault> {
        Ok(())
    }
    fn start_gripper(&mut self, _close: bool, _now: Duration) -> Result<(), ArmFault> {
        Ok(())
    }
    fn poll(&mut self, _now: Duration) -> Result<SkillStatus, ArmFault> {
        Ok(SkillStatus::Done { object_held: false })
    }
}

impl ArmDevice for ParkedArm {
    fn update(&mut self, _now: Duration) -> Result<ArmSnapshot, ArmFault> {
        Ok(ArmSnapshot {
            robot_mode: 7,
            ..ArmSnapshot::default()
        })
    }
    fn stop(&mut self, _now: Duration) {}
}

/// One sample: a fresh executive, its mission started, the plan published, the first motion
/// frame awaited. Returns plan publish -> first non-zero 0x500 frame.
#[allow(
    clippy::too_many_lines,
    reason = "one measured mission start, step by step"
)]
fn one(namespace: &str) -> Result<Duration, BenchError> {
    let clock: Arc<dyn Clock> = Arc::new(grop_clock::WallClock);
    let bus = MemoryBus::new();
    let mut tap = bus.join();
    let mut scene = world::Scene::empty_paper_room();
    scene.targets = vec![world::UnloadTarget::on_center_line(0.0)];
    let robot = world::RobotConfig::default();
    let docking = grop_onboard::docking::Docking::new(scene.clone(), &robot);
    let exec_node = IpcNode::new(namespace, "executive").step("the executive's node")?;
    let node = IpcNode::new(namespace, "harness").step("the harness's node")?;
    let mut exec = Executive::new(
        // The harness plays the planner and the localiser.
        ExecutiveConfig {
            inputs: grop_onboard::executive::inputs::InputSources::all("harness"),
            ..ExecutiveConfig::for_robot(&robot)
        },
        Arc::clone(&clock),
        bus.join(),
        ParkedArm,
        &exec_node,
        scene.clone(),
        1,
    )
    .step("the executive")?;
    let mut base = SimRmpNode::new(bus.join(), SimRmp::new(SimConfig::default()));
    let plans = node.publisher::<TaskPlanMsg>().step("the plan publisher")?;
    let poses = node.publisher::<BasePoseMsg>().step("the fix publisher")?;
    let health = node
        .publisher::<HeartbeatMsg>()
        .step("the heartbeat publisher")?;
    let enable = node
        .publisher::<grop_ipc::OperatorEnableMsg>()
        .step("the enable publisher")?;
    let requests = node
        .subscriber::<ReplanRequestMsg>()
        .step("the request subscriber")?;
    let start = scene.robot_start;
    let goal = [start.x_m, start.y_m + 1.2, start.yaw_rad];
    let target = scene.targets[0].as_array();

    let cycle = Duration::from_millis(2);
    let begin = clock.now();
    let mut deadline = begin;
    let mut next_fix = begin;
    let mut plan_at: Option<Duration> = None;
    let mut enable_sent = false;
    loop {
        let now = clock.now();
        if now.saturating_sub(begin) > Duration::from_secs(20) {
            return Err(BenchError::Timeout {
                what: format!(
                    "a motion frame (mission {:?}, plan published: {})",
                    exec.state(),
                    plan_at.is_some()
                ),
                after: Duration::from_secs(20),
            });
        }
        base.poll(now).step("the simulated base")?;
        if now >= next_fix {
            next_fix = now + Duration::from_millis(100);
            // The base has not moved yet when the sample ends: the start pose is exact.
            poses
                .publish(&BasePoseMsg::fix(
                    ns(now),
                    ns(now),
                    PoseFixKind::Global,
                    [start.x_m, start.y_m, start.yaw_rad],
                    0.01,
                    0.01,
                ))
                .step("publishing a fix")?;
            health
                .publish_with(|h| {
                    h.seq = ns(now);
                    h.pid = std::process::id();
                    h.stamp_ns = ns(now);
                    h.set_role(ProcessRole::Planner);
                })
                .step("publishing a heartbeat")?;
        }
        while let Some(req) = requests.try_recv().step("reading plan requests")? {
            if plan_at.is_none() && exec.state() == MissionState::Running {
                let id = req.request_id;
                // One leg to a standing spot at the table, docked as the planner node plans it
                // (the path goes to the pre-goal). The unload after it is not part of the
                // measurement (nothing is on the tray to unload: the executive would refuse it).
                let mut leg = [
                    TaskStep::navigate(goal[0], goal[1], goal[2], 3.0),
                    TaskStep::unload(0, TableSide::Near, target, goal, 0.9),
                ];
                docking.annotate(
                    &mut leg,
                    req.pose,
                    req.flags & grop_ipc::REQUEST_AT_TABLE != 0,
                );
                let steps = [leg[0]];
                let published = clock.now();
                plans
                    .publish_with(|p| {
                        p.plan_id = 1;
                        p.answers_request = id;
                        p.stamp_ns = ns(published);
                        p.object_count = 1;
                        let _ = p.set_steps(&steps);
                    })
                    .step("publishing the plan")?;
                plan_at = Some(published);
            }
        }
        exec.cycle(clock.now());
        if !enable_sent {
            enable_sent = true;
            // The operator's enable, once the executive runs (a start is not an enable).
            enable
                .publish(&grop_ipc::OperatorEnableMsg {
                    seq: 1,
                    stamp_ns: ns(clock.now()),
                    pid: std::process::id(),
                    reserved: 0,
                })
                .step("publishing the enable")?;
        }
        while let Some(frame) = tap.try_recv().step("the bus tap")? {
            let motion = frame.id() == CanId::Standard(rmp_codec::v3::MOTION_ID)
                && frame.data().iter().any(|b| *b != 0);
            if let (true, Some(at)) = (motion, plan_at) {
                return Ok(clock.now().saturating_sub(at));
            }
        }
        deadline += cycle;
        clock.sleep_until(deadline);
    }
}

/// `samples` plan-to-motion measurements, each with a fresh executive.
pub fn plan_to_motion(samples: usize, namespace: &str) -> Result<Summary, BenchError> {
    let mut ns_samples = Vec::with_capacity(samples);
    for i in 0..samples {
        let d = one(&format!("{namespace}-{i}"))?;
        ns_samples.push(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    }
    Ok(Summary::of(&mut ns_samples))
}

#[cfg(test)]
mod tests {
    /// The harness is the planner and the localiser the executive accepts (its node is named in
    /// the executive's inputs, its heartbeats carry its pid and an advancing sequence): the
    /// plan reaches the base. Fails when anything it publishes is refused.
    #[test]
    fn one_plan_reaches_the_base() {
        let ns = format!("test-{}-plan-motion", std::process::id());
        if let Err(e) = super::plan_to_motion(1, &ns) {
            panic!("{e}");
        }
    }
}
