//! The tray on the core's bench: a plan's loads against the tray, the station asked once per
//! load step, the plan's slots followed and checked (docs/runtime.md, "Load").

use super::*;

#[test]
fn a_plan_that_overloads_the_tray_is_refused() {
    let mut b = Bench::with_objects(5);
    let request = b.until_request();
    let p = plan(
        request,
        &[
            TaskStep::navigate(2.0, 1.0, 0.0, 3.0),
            TaskStep::load(0b1111, 2.0, 1.0),
        ],
    );
    b.step(|i| i.plans = std::slice::from_ref(&p));
    assert_eq!(b.core.stats().plans, 0);
    assert!(
        b.events
            .iter()
            .any(|(k, d)| *k == EventKind::StaleInput && d.contains("tray")),
        "{:?}",
        b.events
    );
    assert_eq!(b.core.state(), MissionState::Running);
    // A planner that keeps answering the same: the mission is given up, not spun for ever.
    for _ in 1..crate::executive::PLANS_REFUSED_LIMIT {
        b.step(|i| i.plans = std::slice::from_ref(&p));
    }
    assert_eq!(
        b.core.state(),
        MissionState::Aborted(AbortReason::PlansRefused)
    );
    assert_eq!(b.out.velocity, Twist::ZERO);
}

#[test]
fn each_load_step_asks_the_station_once_for_its_own_mask() {
    let mut b = Bench::with_objects(3);
    // Standing at the station (1, 1): two load steps in a row (two trips' loads).
    assert!(
        b.running_with(&[
            TaskStep::load(0b001, 1.0, 1.0),
            TaskStep::load(0b100, 1.0, 1.0)
        ])
        .is_none(),
        "no leg before a load at the start"
    );
    let mut asked = Vec::new();
    for _ in 0..400 {
        b.step(|_| {});
        if let Some(r) = b.out.load_request {
            asked.push((
                r.request_id,
                r.object_mask,
                r.station_m,
                r.plan_id,
                r.step_index,
            ));
        }
        if b.core.state() == MissionState::Finished {
            break;
        }
    }
    // The first request went out in the cycle the plan was taken (inside running_with).
    let first = b
        .events
        .iter()
        .filter(|(k, _)| *k == EventKind::LoadRequested)
        .map(|(_, d)| d.as_str())
        .collect::<Vec<_>>();
    assert_eq!(first.len(), 2, "{first:?}");
    assert!(
        first[0].contains("request 1") && first[0].contains("0x1"),
        "{first:?}"
    );
    assert_eq!(
        asked,
        vec![(2, 0b100, [1.0, 1.0], 7, 1)],
        "the second, once"
    );
    assert_eq!(b.core.state(), MissionState::Finished);
    // The tray holds the two objects in the slots the station fills (object order).
    assert_eq!(&b.core.slots[..3], &[Some(0), Some(2), None]);
}

/// The tray is the plan's: a load puts its objects into the slots the plan gives them (not
/// the first free ones), and a plan whose slots do not add up with what is on the tray is
/// refused, naming the step.
#[test]
fn the_core_loads_into_the_plan_s_slots_and_refuses_a_tray_that_does_not_add_up() {
    let mut b = Bench::with_objects(3);
    let mut load = TaskStep::load(0b011, 1.0, 1.0);
    load.tray_slot = 0b0110;
    assert!(b.running_with_as_planned(&[load]).is_none());
    for _ in 0..400 {
        b.step(|_| {});
        if b.core.state() == MissionState::Finished {
            break;
        }
    }
    assert_eq!(b.core.state(), MissionState::Finished);
    assert_eq!(&b.core.slots[..4], &[None, Some(0), Some(1), None]);

    // An unload from a slot its object is not in: refused before anything moves.
    let mut b = Bench::with_objects(3);
    let request = b.until_request();
    let goal = [1.0, 5.2, std::f64::consts::FRAC_PI_2];
    let mut unload = TaskStep::unload(1, grop_ipc::TableSide::Near, [1.0, 6.0, 0.8], goal, 0.8);
    unload.tray_slot = 0;
    let mut load = TaskStep::load(0b011, 1.0, 1.0);
    load.tray_slot = 0b0011;
    let p = plan(
        request,
        &[
            load,
            TaskStep::navigate(goal[0], goal[1], goal[2], 10.0),
            unload,
        ],
    );
    b.step(|i| i.plans = std::slice::from_ref(&p));
    assert_eq!(b.core.stats().plans, 0);
    assert!(
        b.events.iter().any(|(k, d)| *k == EventKind::StaleInput
            && d.contains("step 2: object 1 is not in tray slot 0")),
        "{:?}",
        b.events
    );
    // The same plan with the slot the load gave object 1: taken.
    let mut p = p;
    p.steps[2].tray_slot = 1;
    b.step(|i| i.plans = std::slice::from_ref(&p));
    assert_eq!(b.core.stats().plans, 1, "{:?}", b.events);
}
