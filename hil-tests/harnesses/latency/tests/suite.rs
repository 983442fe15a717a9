//! The suite's measurements, run with tiny sample counts: they finish, their results are well
//! formed (counts right, p50 <= p99 <= max), the peer processes are reaped. No timing is
//! asserted (timings are benchmarks, not tests), and nothing here needs root: a refused
//! real-time setting is reported, not fatal.

use std::path::Path;
use std::time::Duration;

use grop_clock::rt::RtSettings;
use latency::camera::{CameraConfig, Transport, WaitMode};
use latency::can_loop::CanConfig;
use latency::jitter::{JitterConfig, LoopConfig};
use latency::peer::Peer;
use latency::suite::{SuiteConfig, SuiteResults};

fn peer() -> &'static Path {
    Path::new(env!("CARGO_BIN_EXE_grop-latency-peer"))
}

#[test]
fn camera_frames_cross_every_transport_in_both_modes() {
    let config = CameraConfig {
        rounds: 2,
        frames_per_round: 3,
        warmup_frames: 2,
        gap: Duration::from_micros(100),
    };
    let result = latency::camera::measure(peer(), &config).unwrap();
    assert_eq!(result.image_bytes, 921_600);
    assert!(result.service.contains(&std::process::id().to_string()));
    assert_eq!(result.modes.len(), 2);
    for mode in [WaitMode::Polling, WaitMode::Sleeping] {
        let m = result.mode(mode).unwrap();
        assert_eq!(m.transports.len(), 5);
        for t in &m.transports {
            assert_eq!(t.total.count, 6, "{:?} {mode:?}", t.transport);
            assert!(t.total.is_ordered(), "{t:?}");
            assert!(t.total.p50_ns > 0, "{t:?}");
            match t.transfer {
                Some(s) => {
                    assert_eq!(s.count, 6);
                    assert!(s.is_ordered() && s.p50_ns <= t.total.max_ns);
                }
                None => assert!(matches!(
                    t.transport,
                    Transport::GropIpc | Transport::GropIpcFrame
                )),
            }
        }
        assert!(
            m.ratio_p50(Transport::UnixSocket, Transport::Iceoryx2)
                .is_some()
        );
    }
}

#[test]
fn two_runs_use_different_services() {
    let a = latency::names::unique("cam");
    let b = latency::names::unique("cam");
    assert_ne!(a, b);
    assert!(a.contains(&std::process::id().to_string()));
}

#[test]
fn loops_report_lateness_and_their_rt_settings() {
    let config = LoopConfig {
        hz: 500,
        cycles: 20,
        loaded: true,
        rt: "slack=1,stack=64K".parse().unwrap(),
        work: Duration::from_micros(20),
    };
    let r = latency::jitter::measure_loop(peer(), &config).unwrap();
    assert_eq!(r.summary.count, 20);
    assert!(r.summary.p50 <= r.summary.p99 && r.summary.p99 <= r.summary.max);
    assert!(r.load_cpu.is_some());
    assert_eq!(r.rt_report.len(), 6, "{:?}", r.rt_report);
    assert!(
        r.rt_report
            .iter()
            .any(|l| l.starts_with("timer slack: applied"))
    );
    // SCHED_FIFO was not asked for: the loop ran under the default policy.
    assert!(!r.fifo_applied);
    assert_eq!(r.policy, "SCHED_OTHER");

    let idle = latency::jitter::measure_loop(
        peer(),
        &LoopConfig {
            loaded: false,
            rt: RtSettings::OFF,
            cycles: 5,
            ..config
        },
    )
    .unwrap();
    assert_eq!(idle.summary.count, 5);
    assert!(idle.rt_report.is_empty());
    assert_eq!(idle.load_cpu, None);
}

#[test]
fn can_commands_get_decoded_replies() {
    let r = latency::can_loop::measure(
        peer(),
        &CanConfig {
            samples: 20,
            warmup: 5,
        },
    )
    .unwrap();
    assert_eq!(r.first_frame.count, 20);
    assert_eq!(r.decoded.count, 20);
    assert!(r.first_frame.is_ordered() && r.decoded.is_ordered());
    assert!(r.first_frame.p50_ns <= r.decoded.p50_ns);
    assert_eq!(r.frames_per_set, 8);
}

#[test]
fn allocation_counts_come_back_for_every_case() {
    let results = latency::alloc_count::measure(peer(), 10, 5).unwrap();
    let cases: Vec<&str> = results.iter().map(|r| r.case.as_str()).collect();
    assert_eq!(
        cases,
        [
            "driver-tick-vcan",
            "sim-poll-vcan",
            "driver-tick-memory",
            "sim-poll-memory",
            "vcan-send",
            "vcan-recv",
            "frame-publish",
            "frame-receive",
            "loop-stats"
        ]
    );
    for r in &results {
        assert_eq!(r.cycles, 10);
        assert_ne!(latency::alloc_count::case_label(&r.case), "unknown case");
    }
    let loop_stats = results.iter().find(|r| r.case == "loop-stats").unwrap();
    assert_eq!(loop_stats.allocs, 0, "LoopStats allocates nothing");
}

#[test]
fn the_peer_is_spawned_and_reaped() {
    let (peer, ready) = Peer::spawn(
        peer(),
        &["spin".to_owned(), "--cpu".to_owned(), "0".to_owned()],
    )
    .unwrap();
    assert_eq!(ready, "");
    let pid = peer.pid();
    assert!(Path::new(&format!("/proc/{pid}")).exists());
    assert!(
        peer.notes()
            .iter()
            .any(|l| l.starts_with("rt CPU affinity"))
    );
    drop(peer);
    // Reaped: no process and no zombie left.
    assert!(
        !Path::new(&format!("/proc/{pid}")).exists(),
        "peer {pid} left behind"
    );

    // A peer that fails says why.
    let err = Peer::spawn(
        self::peer(),
        &[
            "rmp-sim".to_owned(),
            "--bus".to_owned(),
            "bad/name".to_owned(),
        ],
    )
    .err()
    .unwrap();
    assert!(err.to_string().contains("bad/name"), "{err}");
}

#[test]
fn the_whole_suite_runs_quick_and_reports() {
    let mut config = SuiteConfig::quick("slack=1".parse().unwrap());
    config.camera.rounds = 1;
    config.camera.frames_per_round = 2;
    config.camera.warmup_frames = 1;
    config.jitter = JitterConfig {
        cycles_50hz: 3,
        cycles_500hz: 10,
        ..config.jitter
    };
    config.can.samples = 10;
    config.alloc_cycles = 5;
    config.alloc_warmup = 5;
    let mut steps = Vec::new();
    let results: SuiteResults =
        latency::suite::run(peer(), &config, |s| steps.push(s.to_owned())).unwrap();
    assert_eq!(steps.len(), 4);
    assert_eq!(results.jitter.len(), 8);
    let md =
        latency::report::markdown(&results, "cargo run --release -p grop-cli -- latency", None);
    for heading in [
        "## Targets",
        "## Camera frame across two processes",
        "## Loop period jitter",
        "## CAN command to feedback",
        "## Allocations per steady-state cycle",
        latency::report::PIPELINE_HEADING,
    ] {
        assert!(md.contains(heading), "{heading} missing");
    }
    assert!(md.contains("cargo run --release -p grop-cli -- latency"));
    let with_table = latency::report::markdown(
        &results,
        "x",
        Some("| stage | p50 |\n|---|---|\n| frame -> plan | 1 |".to_owned()),
    );
    assert!(with_table.contains("| frame -> plan | 1 |"));
}
