//! Who may command (docs/security.md): a forger process (`grop-forger`) publishes into a
//! running mission's namespace. As the same OS user it cannot open a second publisher on
//! `plan/task` or `base/pose`, and its planner heartbeats (its own node, a second
//! `grop-planner`, one claiming the real planner's pid) are refused and reported by the
//! executive: the mission goes on, and a dead planner is still noticed. As another OS user it
//! cannot join the namespace at all.
#![allow(
    unsafe_code,
    reason = "libc::geteuid: the test runs the forger as another user when root"
)]
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use hil_world::mission::{self, MissionSpec, RunningMission};
use hil_world::report::{MissionEnd, WorldReport};

mod common;
use common::spec;

fn forger_binary(bins: &mission::Binaries) -> PathBuf {
    bins.world.with_file_name("grop-forger")
}

/// The namespace the mission runner wrote into the run's deployment file.
fn namespace(dir: &Path) -> String {
    let text = std::fs::read_to_string(dir.join("deployment.toml")).expect("deployment.toml");
    text.lines()
        .find_map(|l| l.strip_prefix("namespace = "))
        .map(|v| v.trim().trim_matches('"').to_owned())
        .expect("a namespace line")
}

fn forge(forger: &Path, namespace: &str, for_s: f64, claim_pid: u32) -> Output {
    Command::new(forger)
        .args(["--namespace", namespace, "--for-s", &for_s.to_string()])
        .args(["--claim-pid", &claim_pid.to_string()])
        .output()
        .expect("grop-forger runs")
}

/// Starts the mission and waits until the executive has started its first plan.
fn start_and_wait_for_plan(spec: &MissionSpec) -> (RunningMission, mission::Binaries) {
    let bins = mission::binaries(true).expect("the world and onboard binaries build");
    let running = mission::start(spec, &bins).expect("mission starts");
    let started = running.wait_for_line(
        Duration::from_secs(60),
        |l| l.contains("PlanStarted"),
        &mut |_| {},
    );
    assert!(started.is_some(), "no plan started");
    (running, bins)
}

fn refusals(report: &WorldReport) -> Vec<&str> {
    report
        .events
        .iter()
        .filter(|e| e.kind == "InputRefused")
        .map(|e| e.detail.as_str())
        .collect()
}

fn assert_refused_and_reported(out: &Output, report: &WorldReport, planner_pid: u32) {
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "grop-forger: {said}");
    // As the same user: no second publisher on the single-writer topics.
    assert!(said.contains("forger: plan/task: no publisher"), "{said}");
    assert!(said.contains("forger: base/pose: no publisher"), "{said}");
    assert!(said.contains("sent 0 plans, 0 fixes"), "{said}");
    let sent_some = said
        .lines()
        .filter(|l| l.contains("planner heartbeats"))
        .all(|l| !l.contains("sent 0 "));
    assert!(sent_some, "{said}");
    let refused = refusals(report);
    for expected in [
        "node `forger`".to_owned(),
        "is a second publisher".to_owned(),
        format!("claims pid {planner_pid}"),
    ] {
        assert!(
            refused
                .iter()
                .any(|d| d.starts_with("health (planner) refused") && d.contains(&expected)),
            "no refusal saying {expected:?} in {refused:#?}\nforger: {said}"
        );
    }
}

#[test]
fn a_forger_beside_a_mission_is_refused_and_reported_and_the_mission_goes_on() {
    let spec = spec("forger", 4);
    let (running, bins) = start_and_wait_for_plan(&spec);
    let planner_pid = running.planner.id();
    let out = forge(
        &forger_binary(&bins),
        &namespace(&spec.dir),
        1.0,
        planner_pid,
    );
    let report = running
        .finish(Duration::from_secs(300), &mut |_| {})
        .expect("the world reports");
    assert_eq!(report.end, MissionEnd::Finished, "{:#?}", report.events);
    assert!(
        !report
            .events
            .iter()
            .any(|e| e.kind == "PeerLost" || e.kind == "MissionAborted"),
        "{:#?}",
        report.events
    );
    assert_refused_and_reported(&out, &report, planner_pid);
}

/// The hazard of the issue: forged heartbeats hid a dead planner. In real time (pace 1), with
/// the forger sending planner heartbeats every 20 ms, killing the planner still aborts the
/// mission on the missing heartbeats, whether the forger joined before the death (a second
/// publisher) or after it (a successor, which the executive does not accept either).
#[test]
fn forged_heartbeats_do_not_hide_a_dead_planner() {
    let spec = MissionSpec {
        pace: Some(1.0),
        ..spec("forger-dead-planner", 5)
    };
    let (mut running, bins) = start_and_wait_for_plan(&spec);
    let planner_pid = running.planner.id();
    let forger = forger_binary(&bins);
    let ns = namespace(&spec.dir);
    let forging = std::thread::spawn(move || forge(&forger, &ns, 3.0, planner_pid));
    std::thread::sleep(Duration::from_millis(500));
    running.kill_planner();
    let out = forging.join().expect("the forger's thread");
    let report = running
        .finish(Duration::from_secs(60), &mut |_| {})
        .expect("the world reports");
    assert_eq!(report.end, MissionEnd::Aborted, "{:#?}", report.events);
    common::planner_death_noticed(&report, "despite the forged heartbeats");
    assert_refused_and_reported(&out, &report, planner_pid);
}

/// A hostile local user: the forger run as `nobody` cannot join the namespace (iceoryx2's
/// folder is this user's, mode 0700). Needs root to switch users; says so and skips otherwise.
#[test]
fn a_forger_of_another_user_cannot_join() {
    // SAFETY: geteuid has no preconditions.
    if unsafe { libc::geteuid() } != 0 {
        eprintln!(
            "SKIPPED a_forger_of_another_user_cannot_join: not root, cannot run the forger as another uid"
        );
        return;
    }
    let ns = mission::unique_run_name("forger-uid");
    let node = grop_ipc::IpcNode::new(&ns, "grop-planner").unwrap();
    let _plans = node.publisher::<grop_ipc::TaskPlanMsg>().unwrap();
    let mut beats = node
        .admitting_subscriber::<grop_ipc::HeartbeatMsg>("grop-planner", |_| true)
        .unwrap();
    let bins = mission::binaries(true).expect("the binaries build");
    // A copy `nobody` can read and run, whatever the build folder's modes.
    let copy = std::env::temp_dir().join(format!("{ns}-grop-forger"));
    std::fs::copy(forger_binary(&bins), &copy).unwrap();
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&copy, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    use std::os::unix::process::CommandExt;
    let out = Command::new(&copy)
        .args(["--namespace", &ns, "--for-s", "0.5"])
        .uid(65534)
        .gid(65534)
        .current_dir(std::env::temp_dir())
        .output()
        .expect("grop-forger runs as nobody");
    let _ = std::fs::remove_file(&copy);
    let said = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(2), "{said}");
    assert!(said.contains("cannot join namespace"), "{said}");
    assert!(
        beats.try_recv().unwrap().is_none(),
        "nothing arrived from the other user"
    );
}
