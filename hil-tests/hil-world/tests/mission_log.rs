//! The mission log (MCAP) over the closed loop: what it holds, and that the same mission twice
//! on the simulated clock logs the same messages at the same simulated times.
#![allow(
    clippy::too_many_lines,
    reason = "a test scenario (or the fuzz harness's) reads top to bottom as one story"
)]

use std::time::Duration;

use grop_onboard::mission_log::replay::{ReplayOptions, replay};
use grop_onboard::mission_log::{
    Channel, LogWriter, LoggedMessage, MissionLog, Overflow, WriterConfig,
};
use hil_world::mission::{self, MissionSpec};
use hil_world::report::MissionEnd;

mod common;

fn logged_spec(test: &str, seed: u64) -> MissionSpec {
    let spec = common::spec(test, seed);
    MissionSpec {
        log: Some(spec.dir.join("mission.mcap")),
        progress_s: 0.0,
        ..spec
    }
}

/// The first message where two logs differ, described.
fn first_difference(a: &[LoggedMessage], b: &[LoggedMessage]) -> Option<String> {
    // Wall-clock measurements (`/timing/...`) differ run to run by nature.
    let behaviour = |m: &&LoggedMessage| !m.channel.topic().starts_with("/timing/");
    let a: Vec<&LoggedMessage> = a.iter().filter(behaviour).collect();
    let b: Vec<&LoggedMessage> = b.iter().filter(behaviour).collect();
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        if x.channel != y.channel || x.log_time != y.log_time || x.data != y.data {
            return Some(format!(
                "message {i}: {:?} at {} ns: {}\n  vs {:?} at {} ns: {}",
                x.channel,
                x.log_time,
                String::from_utf8_lossy(&x.data[..x.data.len().min(300)]),
                y.channel,
                y.log_time,
                String::from_utf8_lossy(&y.data[..y.data.len().min(300)])
            ));
        }
    }
    (a.len() != b.len()).then(|| format!("lengths differ: {} vs {}", a.len(), b.len()))
}

#[test]
fn the_same_mission_twice_logs_the_same_messages_and_a_replay_reproduces_them() {
    let bins = mission::binaries(true).expect("the world and onboard binaries build");
    let specs = [logged_spec("log-a", 4), logged_spec("log-b", 4)];
    // Side by side: the two runs share the machine, which is the point.
    let running: Vec<_> = specs
        .iter()
        .map(|s| mission::start(s, &bins).expect("mission starts"))
        .collect();
    let reports: Vec<_> = running
        .into_iter()
        .map(|r| {
            r.finish(Duration::from_secs(600), &mut |_| {})
                .expect("the world reports")
        })
        .collect();
    for r in &reports {
        assert_eq!(r.end, MissionEnd::Finished, "{:#?}", r.events);
    }
    let logs: Vec<MissionLog> = specs
        .iter()
        .map(|s| MissionLog::read(s.log.as_deref().expect("logged")).expect("the log reads"))
        .collect();
    for log in &logs {
        assert!(log.truncated.is_none(), "{:?}", log.truncated);
        assert_eq!(log.unknown, 0);
        assert_eq!(log.log_format, grop_onboard::mission_log::LOG_FORMAT);
        for c in Channel::ALL {
            assert!(log.channel(c).count() > 0, "nothing on {}", c.topic());
        }
        // Every plan's camera frame is in the log.
        let frames: Vec<u64> = log
            .channel(Channel::CameraFrame)
            .map(|m| grop_onboard::mission_log::codec::camera_frame_id(&m.data).expect("frame id"))
            .collect();
        for plan in log.channel(Channel::TaskPlan) {
            let v: serde_json::Value = serde_json::from_slice(&plan.data).expect("plan json");
            let id = v["source_frame_id"].as_u64().expect("source_frame_id");
            assert!(
                frames.contains(&id),
                "frame {id} of a plan is not logged ({frames:?})"
            );
        }
        // The mission's files are in the metadata, for a replay.
        let meta = &log.metadata[grop_onboard::mission_log::MISSION_METADATA];
        assert!(meta["map"].contains("targets"), "{meta:?}");
        assert!(meta["deployment"].contains("namespace"));
    }
    if let Some(d) = first_difference(&logs[0].messages, &logs[1].messages) {
        panic!(
            "the two runs logged different messages ({} and {}):\n{d}",
            logs[0].messages.len(),
            logs[1].messages.len()
        );
    }
    assert_eq!(logs[0].digest(), logs[1].digest());

    // The planner and the executive re-run against the first log's inputs do the same again.
    let path = specs[0].log.as_deref().expect("logged");
    let report = replay(path, &ReplayOptions::default()).expect("the replay runs");
    assert!(
        report.first_difference.is_none(),
        "an unchanged build differs from its own log: {}",
        report
            .first_difference
            .as_ref()
            .map(|d| d.to_string())
            .unwrap_or_default()
    );
    assert_eq!(report.arm_mismatches, 0);
    assert_eq!(report.recorded, report.replayed);

    // A log where one thing the executive did is changed: the replay names that message.
    let behaviour: Vec<&LoggedMessage> = logs[0]
        .messages
        .iter()
        .filter(|m| !m.channel.topic().starts_with("/timing/"))
        .collect();
    let target = behaviour
        .iter()
        .enumerate()
        .filter(|(_, m)| m.channel == Channel::BaseState)
        .nth(100)
        .map(|(i, _)| i)
        .expect("100 base states");
    let tampered = specs[0].dir.join("tampered.mcap");
    let writer = LogWriter::create(
        &tampered,
        logs[0].metadata.clone(),
        WriterConfig {
            overflow: Overflow::Block,
            ..WriterConfig::default()
        },
    )
    .expect("writing the tampered log");
    let mut index = 0;
    for m in &logs[0].messages {
        let mut data = m.data.clone();
        if !m.channel.topic().starts_with("/timing/") {
            if index == target {
                let text = String::from_utf8(data).expect("json");
                assert!(text.contains("\"link_up\":1"), "{text}");
                data = text.replace("\"link_up\":1", "\"link_up\":0").into_bytes();
            }
            index += 1;
        }
        assert!(writer.push(m.channel, m.log_time, m.publish_time, data));
    }
    writer.finish().expect("the tampered log closes");
    let report = replay(&tampered, &ReplayOptions::default()).expect("the replay runs");
    let d = report.first_difference.expect("the change is found");
    assert_eq!(d.index, target, "{d}");
    let (channel, _, recorded) = d.recorded.expect("recorded message");
    assert_eq!(channel, Channel::BaseState);
    assert!(recorded.contains("\"link_up\":0"), "{recorded}");

    for s in &specs {
        let _ = std::fs::remove_dir_all(&s.dir);
    }
}
