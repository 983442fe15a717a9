//! `grop-forger --namespace NS [--for-s S] [--claim-pid PID]`: another program on the robot
//! computer that publishes into a mission's namespace (docs/security.md, the tests in
//! `tests/forger.rs`). For `S` seconds (wall) it
//!
//! - tries to open publishers on `plan/task` and `base/pose`, and, where it gets one, publishes
//!   plans answering the executive's newest request (a leg 3 m away) and fixes 1 m off;
//! - sends planner heartbeats at 50 Hz as node `forger`, as a second node `grop-planner` with
//!   its own pid, and as that node claiming pid `PID` (the real planner's).
//!
//! It prints one line per attempt and a summary, and exits 0; 2 when it cannot join the
//! namespace at all (another OS user: iceoryx2's folder is not theirs).

use std::time::{Duration, Instant};

use clap::Parser;
use grop_ipc::{
    BasePoseMsg, HeartbeatMsg, IpcNode, PoseFixKind, ProcessRole, ReplanRequestMsg, TaskPlanMsg,
    TaskStep, TopicPublisher,
};

#[derive(Parser, Debug)]
#[command(
    name = "grop-forger",
    about = "publishes forged commands into a namespace"
)]
struct Args {
    /// The namespace to publish into.
    #[arg(long)]
    namespace: String,
    /// How long to keep publishing (wall seconds).
    #[arg(long, default_value_t = 2.0)]
    for_s: f64,
    /// The pid the claiming heartbeats carry (default: this process's plus one).
    #[arg(long)]
    claim_pid: Option<u32>,
}

fn try_publisher<T: grop_ipc::Topic>(node: &IpcNode) -> Option<TopicPublisher<T>> {
    match node.publisher::<T>() {
        Ok(p) => {
            println!("forger: {}: publisher opened", T::NAME);
            Some(p)
        }
        Err(e) => {
            println!("forger: {}: no publisher: {e}", T::NAME);
            None
        }
    }
}

fn main() {
    let args = Args::parse();
    let pid = std::process::id();
    let nodes = IpcNode::new(&args.namespace, "forger").and_then(|forger| {
        IpcNode::new(&args.namespace, "grop-planner").map(|copy| (forger, copy))
    });
    let (forger, copy) = match nodes {
        Ok(n) => n,
        Err(e) => {
            println!("forger: cannot join namespace {}: {e}", args.namespace);
            std::process::exit(2);
        }
    };
    let plans = try_publisher::<TaskPlanMsg>(&forger);
    let fixes = try_publisher::<BasePoseMsg>(&forger);
    let requests = forger.subscriber::<ReplanRequestMsg>().ok();
    let beats: Vec<(&str, u32, TopicPublisher<HeartbeatMsg>)> = [
        ("as node forger", pid, &forger),
        ("as a second grop-planner", pid, &copy),
        (
            "as grop-planner claiming another pid",
            args.claim_pid.unwrap_or(pid.wrapping_add(1)),
            &copy,
        ),
    ]
    .into_iter()
    .filter_map(
        |(what, claimed, node)| match node.publisher::<HeartbeatMsg>() {
            Ok(p) => Some((what, claimed, p)),
            Err(e) => {
                println!("forger: health {what}: no publisher: {e}");
                None
            }
        },
    )
    .collect();

    let start = Instant::now();
    let mut sent = vec![0u64; beats.len()];
    let (mut plans_sent, mut fixes_sent, mut request) = (0u64, 0u64, 0u64);
    let mut seq = 0u64;
    while start.elapsed().as_secs_f64() < args.for_s {
        seq += 1;
        for ((_, claimed, p), n) in beats.iter().zip(sent.iter_mut()) {
            let ok = p.publish_with(|h| {
                h.seq = seq;
                h.pid = *claimed;
                h.set_role(ProcessRole::Planner);
            });
            *n += u64::from(ok.is_ok());
        }
        if let Some(r) = requests.as_ref().and_then(|s| s.latest().ok().flatten()) {
            request = r.request_id;
        }
        if let Some(p) = &plans {
            let step = TaskStep::navigate(3.0, 0.0, 0.0, 10.0);
            let ok = p.publish_with(|m| {
                m.plan_id = 1_000_000 + seq;
                m.answers_request = request;
                m.object_count = 1;
                let _ = m.set_steps(&[step]);
            });
            plans_sent += u64::from(ok.is_ok());
        }
        if let Some(p) = &fixes {
            let fix = BasePoseMsg::fix(seq, 0, PoseFixKind::Global, [1.0, 1.0, 0.0], 0.01, 0.01);
            fixes_sent += u64::from(p.publish(&fix).is_ok());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    for ((what, claimed, _), n) in beats.iter().zip(&sent) {
        println!("forger: sent {n} planner heartbeats {what} (pid {claimed})");
    }
    println!("forger: sent {plans_sent} plans, {fixes_sent} fixes");
}
