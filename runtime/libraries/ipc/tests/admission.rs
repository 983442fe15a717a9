//! Who may publish a command topic (docs/security.md): one publisher per single-writer topic,
//! and an admitting subscriber that accepts only the deployment's node, its own process id and
//! an advancing sequence.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use grop_ipc::{
    Admission, AdmittingSubscriber, BasePoseMsg, HeartbeatMsg, IpcNode, PortError, PoseFixKind,
    ProcessRole, Refusal, Sequenced, TaskPlanMsg,
};

static COUNTER: AtomicU32 = AtomicU32::new(0);

fn unique_namespace(test: &str) -> String {
    format!(
        "test-{}-{}-{test}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

/// The next admission (accepted or refused), waiting up to 5 s.
fn next<T: Sequenced>(sub: &mut AdmittingSubscriber<T>) -> Admission<T> {
    let end = Instant::now() + Duration::from_secs(5);
    loop {
        if let Some(admission) = sub.try_recv().unwrap() {
            return admission;
        }
        assert!(Instant::now() < end, "nothing arrived");
        std::thread::sleep(Duration::from_millis(1));
    }
}

fn refusal<T: Sequenced>(sub: &mut AdmittingSubscriber<T>) -> Refusal {
    match next(sub) {
        Admission::Refused(r) => r,
        Admission::Accepted(m) => panic!("accepted {m:?}"),
    }
}

fn accepted<T: Sequenced>(sub: &mut AdmittingSubscriber<T>) -> grop_ipc::Received<T> {
    match next(sub) {
        Admission::Accepted(m) => m,
        Admission::Refused(r) => panic!("refused: {r}"),
    }
}

fn beat(seq: u64, pid: u32) -> impl FnOnce(&mut HeartbeatMsg) {
    move |h| {
        h.seq = seq;
        h.pid = pid;
        h.set_role(ProcessRole::Planner);
    }
}

fn is_planner(h: &HeartbeatMsg) -> bool {
    h.role() == Ok(ProcessRole::Planner)
}

#[test]
fn single_writer_topics_have_room_for_one_publisher() {
    let ns = unique_namespace("one-writer");
    let planner = IpcNode::new(&ns, "grop-planner").unwrap();
    let other = IpcNode::new(&ns, "other").unwrap();
    let _plans = planner.publisher::<TaskPlanMsg>().unwrap();
    let _fixes = planner.publisher::<BasePoseMsg>().unwrap();
    assert!(matches!(
        other.publisher::<TaskPlanMsg>(),
        Err(PortError::Full {
            port: "publisher",
            ..
        })
    ));
    assert!(matches!(
        other.publisher::<BasePoseMsg>(),
        Err(PortError::Full { .. })
    ));
    // Topics with several writers keep their room.
    let _a = planner.publisher::<HeartbeatMsg>().unwrap();
    let _b = other.publisher::<HeartbeatMsg>().unwrap();
}

#[test]
fn only_the_named_node_is_accepted_and_no_other_process_after_it() {
    let ns = unique_namespace("named");
    let exec = IpcNode::new(&ns, "executive").unwrap();
    let mut plans = exec
        .admitting_subscriber::<TaskPlanMsg>("grop-planner", |_| true)
        .unwrap();
    {
        let forger = IpcNode::new(&ns, "forger").unwrap();
        let p = forger.publisher::<TaskPlanMsg>().unwrap();
        p.publish_with(|m| m.plan_id = 7).unwrap();
        match refusal(&mut plans) {
            Refusal::NotAllowed { sender } => {
                assert_eq!(sender.node, "forger");
                assert_eq!(sender.pid, std::process::id());
            }
            other => panic!("{other:?}"),
        }
    }
    // The forger left; the deployment's planner connects.
    let planner = IpcNode::new(&ns, "grop-planner").unwrap();
    let p = planner.publisher::<TaskPlanMsg>().unwrap();
    p.publish_with(|m| m.plan_id = 1).unwrap();
    assert_eq!(accepted(&mut plans).plan_id, 1);
    p.publish_with(|m| m.plan_id = 1).unwrap();
    assert!(matches!(
        refusal(&mut plans),
        Refusal::NotAdvancing {
            seq: 1,
            last: 1,
            ..
        }
    ));
    p.publish_with(|m| m.plan_id = 2).unwrap();
    assert_eq!(accepted(&mut plans).plan_id, 2);
    // The same process with a new port after closing its old one is still the one, and its
    // sequence goes on.
    drop(p);
    let p = planner.publisher::<TaskPlanMsg>().unwrap();
    p.publish_with(|m| m.plan_id = 2).unwrap();
    assert!(matches!(refusal(&mut plans), Refusal::NotAdvancing { .. }));
    p.publish_with(|m| m.plan_id = 3).unwrap();
    assert_eq!(accepted(&mut plans).plan_id, 3);
    assert_eq!(plans.refused(), 3);
}

/// With `accept_successors` (an input a new process sends each time), the next process of the
/// name is accepted once the first left, its sequence starting again.
#[test]
fn with_successors_a_new_process_takes_over_once_the_first_left() {
    let ns = unique_namespace("successors");
    let exec = IpcNode::new(&ns, "executive").unwrap();
    let mut beats = exec
        .admitting_subscriber::<HeartbeatMsg>("grop-planner", is_planner)
        .unwrap()
        .accept_successors();
    {
        let first = IpcNode::new(&ns, "grop-planner").unwrap();
        let health = first.publisher::<HeartbeatMsg>().unwrap();
        health.publish_with(beat(50, std::process::id())).unwrap();
        assert_eq!(accepted(&mut beats).seq, 50);
    }
    let mut child = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "child_planner_role", "--test-threads", "1"])
        .env("GROP_ADMISSION_CHILD_NAMESPACE", &ns)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let first = accepted(&mut beats);
    assert_eq!((first.seq, first.pid), (1, child.id()));
    drop(first);
    assert_eq!(beats.accepted_pid(), Some(child.id()));
    assert_eq!(beats.refused(), 0);
    let _ = child.kill();
    let _ = child.wait();
}

#[test]
fn heartbeats_of_a_second_copy_a_wrong_pid_or_an_old_sequence_are_refused() {
    let ns = unique_namespace("beats");
    let exec = IpcNode::new(&ns, "executive").unwrap();
    let mut beats = exec
        .admitting_subscriber::<HeartbeatMsg>("grop-planner", is_planner)
        .unwrap();
    let pid = std::process::id();
    let planner = IpcNode::new(&ns, "grop-planner").unwrap();
    let health = planner.publisher::<HeartbeatMsg>().unwrap();
    // Another role's heartbeat is not this input's business.
    let world = IpcNode::new(&ns, "world").unwrap();
    let world_health = world.publisher::<HeartbeatMsg>().unwrap();
    world_health
        .publish_with(|h| h.set_role(ProcessRole::World))
        .unwrap();
    health.publish_with(beat(1, pid)).unwrap();
    assert_eq!(accepted(&mut beats).seq, 1);
    assert_eq!(beats.accepted_pid(), Some(pid));
    // A heartbeat that says it is another process.
    health.publish_with(beat(2, pid + 1)).unwrap();
    assert!(matches!(
        refusal(&mut beats),
        Refusal::PidMismatch { claimed, .. } if claimed == pid + 1
    ));
    // A second node of the same name while the first is connected.
    let copy = IpcNode::new(&ns, "grop-planner").unwrap();
    let copy_health = copy.publisher::<HeartbeatMsg>().unwrap();
    copy_health.publish_with(beat(100, pid)).unwrap();
    assert!(matches!(refusal(&mut beats), Refusal::Second { .. }));
    // A forger's planner heartbeat.
    world_health.publish_with(beat(101, pid)).unwrap();
    assert!(matches!(refusal(&mut beats), Refusal::NotAllowed { .. }));
    // The sequence must advance.
    health.publish_with(beat(1, pid)).unwrap();
    assert!(matches!(refusal(&mut beats), Refusal::NotAdvancing { .. }));
    health.publish_with(beat(3, pid)).unwrap();
    assert_eq!(accepted(&mut beats).seq, 3);
    assert_eq!(beats.refused(), 4);
    assert!(beats.try_recv().unwrap().is_none());
    assert!(beats.service().ends_with("/health"));
}

#[test]
fn fixes_follow_their_publishers_sequence() {
    let ns = unique_namespace("fixes");
    let exec = IpcNode::new(&ns, "executive").unwrap();
    let mut fixes = exec
        .admitting_subscriber::<BasePoseMsg>("localiser", |_| true)
        .unwrap();
    let loc = IpcNode::new(&ns, "localiser").unwrap();
    let p = loc.publisher::<BasePoseMsg>().unwrap();
    let fix = |seq| BasePoseMsg::fix(seq, 0, PoseFixKind::Global, [0.0; 3], 0.01, 0.01);
    p.publish(&fix(5)).unwrap();
    p.publish(&fix(4)).unwrap();
    p.publish(&fix(6)).unwrap();
    assert_eq!(accepted(&mut fixes).seq, 5);
    assert!(matches!(
        refusal(&mut fixes),
        Refusal::NotAdvancing {
            seq: 4,
            last: 5,
            ..
        }
    ));
    assert_eq!(accepted(&mut fixes).seq, 6);
}

/// Role of the child process in `another_process_of_the_name_is_refused_before_and_after_the_first_left`;
/// does nothing when run as an ordinary test.
#[test]
fn child_planner_role() {
    let Ok(ns) = std::env::var("GROP_ADMISSION_CHILD_NAMESPACE") else {
        return;
    };
    let node = IpcNode::new(&ns, "grop-planner").unwrap();
    let health = node.publisher::<HeartbeatMsg>().unwrap();
    let pid = std::process::id();
    for seq in 1..=300 {
        health.publish_with(beat(seq, pid)).unwrap();
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A second process named as the deployment's node is refused while the first runs, and after
/// the first left (a successor: a restart and an impostor look the same).
#[test]
fn another_process_of_the_name_is_refused_before_and_after_the_first_left() {
    let ns = unique_namespace("successor");
    let exec = IpcNode::new(&ns, "executive").unwrap();
    let mut beats = exec
        .admitting_subscriber::<HeartbeatMsg>("grop-planner", is_planner)
        .unwrap();
    let planner = IpcNode::new(&ns, "grop-planner").unwrap();
    let health = planner.publisher::<HeartbeatMsg>().unwrap();
    health.publish_with(beat(1, std::process::id())).unwrap();
    assert_eq!(accepted(&mut beats).seq, 1);
    let mut child = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "child_planner_role", "--test-threads", "1"])
        .env("GROP_ADMISSION_CHILD_NAMESPACE", &ns)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    match refusal(&mut beats) {
        Refusal::Second {
            sender,
            accepted_pid,
        } => {
            assert_eq!(sender.pid, child.id());
            assert_eq!(accepted_pid, std::process::id());
        }
        other => panic!("{other:?}"),
    }
    drop(health);
    drop(planner);
    // Drain what the child sent while the first was connected, then its next ones.
    let end = Instant::now() + Duration::from_secs(5);
    let successor = loop {
        assert!(Instant::now() < end, "no successor refusal");
        match next(&mut beats) {
            Admission::Refused(Refusal::Second { .. }) => continue,
            Admission::Refused(r) => break r,
            Admission::Accepted(m) => panic!("accepted the successor's {m:?}"),
        }
    };
    assert!(
        matches!(&successor, Refusal::Successor { sender, .. } if sender.pid == child.id()),
        "{successor:?}"
    );
    let _ = child.kill();
    let _ = child.wait();
}
