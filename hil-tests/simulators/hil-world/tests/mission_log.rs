//! The mission log (MCAP) over the closed loop: what it holds, and that the same mission twice
//! on the simulated clock logs the same messages at the same simulated times, also when one of
//! the two serves the live view (Foxglove WebSocket) to a viewer, a stalled client and a client
//! that tries to publish.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message
#![allow(
    clippy::too_many_lines,
    reason = "a test scenario (or the fuzz harness's) reads top to bottom as one story"
)]

use std::collections::BTreeMap;
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use serde_json::Value;
use tungstenite::Message;
use tungstenite::client::IntoClientRequest;

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

const SUBPROTOCOL: &str = "foxglove.websocket.v1";

type Ws = tungstenite::WebSocket<TcpStream>;

/// A Foxglove WebSocket client connected to `addr`, past the handshake.
fn connect(addr: SocketAddr) -> Ws {
    let stream = TcpStream::connect(addr).expect("connecting to the live view");
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .expect("read timeout");
    let mut request = format!("ws://{addr}/")
        .into_client_request()
        .expect("request");
    request.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        SUBPROTOCOL.parse().expect("header value"),
    );
    let (ws, response) = tungstenite::client(request, stream).expect("handshake");
    assert_eq!(
        response.headers().get("Sec-WebSocket-Protocol"),
        Some(&SUBPROTOCOL.parse().expect("header value"))
    );
    ws
}

fn read_json(ws: &mut Ws) -> Value {
    loop {
        match ws.read().expect("a message") {
            Message::Text(t) => return serde_json::from_str(t.as_str()).expect("JSON"),
            Message::Binary(_) => {}
            other => panic!("unexpected {other:?}"),
        }
    }
}

/// Reads `serverInfo` and `advertise`: the capabilities, and each topic's channel id.
fn hello(ws: &mut Ws) -> (Value, BTreeMap<String, u64>) {
    let info = read_json(ws);
    assert_eq!(info["op"], "serverInfo", "{info}");
    let advertise = read_json(ws);
    assert_eq!(advertise["op"], "advertise", "{advertise}");
    let channels = advertise["channels"]
        .as_array()
        .expect("channels")
        .iter()
        .map(|c| {
            let topic = c["topic"].as_str().expect("topic").to_owned();
            let channel = Channel::from_topic(&topic).expect("a channel of the log");
            assert_eq!(c["encoding"], "json");
            assert_eq!(c["schemaName"], channel.schema_name());
            let schema: Value =
                serde_json::from_str(c["schema"].as_str().expect("schema")).expect("JSON Schema");
            assert_eq!(schema, channel.schema());
            (topic, c["id"].as_u64().expect("id"))
        })
        .collect();
    (info["capabilities"].clone(), channels)
}

fn subscribe(ws: &mut Ws, subscriptions: &[(u64, u64)]) {
    let list: Vec<Value> = subscriptions
        .iter()
        .map(|(id, channel)| serde_json::json!({"id": id, "channelId": channel}))
        .collect();
    let msg = serde_json::json!({"op": "subscribe", "subscriptions": list});
    ws.send(Message::text(msg.to_string())).expect("subscribe");
}

/// A viewer: subscribes to the camera, the pose, the plan and the CAN bus and takes a message
/// of each (and the server's time); then tries to publish and is refused. Returns how many
/// messages of each topic it got.
fn watch(addr: SocketAddr) -> BTreeMap<&'static str, u64> {
    let mut ws = connect(addr);
    let (capabilities, channels) = hello(&mut ws);
    // A viewer: the simulated clock as its time, and nothing a client could command with.
    assert_eq!(capabilities, serde_json::json!(["time"]));
    assert_eq!(channels.len(), Channel::ALL.len());
    let topics = [
        Channel::CameraFrame,
        Channel::BasePose,
        Channel::TaskPlan,
        Channel::Can,
    ];
    let subs: Vec<(u64, u64)> = topics
        .iter()
        .enumerate()
        .map(|(i, c)| (100 + i as u64, channels[c.topic()]))
        .collect();
    subscribe(&mut ws, &subs);
    let mut got: BTreeMap<&'static str, u64> = BTreeMap::new();
    let mut times = 0u64;
    let mut last_time = 0u64;
    let end = Instant::now() + Duration::from_secs(120);
    while (got.len() < topics.len() || times < 2) && Instant::now() < end {
        let Message::Binary(b) = ws.read().expect("a message") else {
            continue;
        };
        match b[0] {
            1 => {
                let sub = u32::from_le_bytes(b[1..5].try_into().expect("4 bytes"));
                let i = usize::try_from(sub).expect("usize") - 100;
                let payload: Value = serde_json::from_slice(&b[13..]).expect("a JSON message");
                if topics[i] == Channel::CameraFrame {
                    assert_eq!(payload["encoding"], "rgb8", "a RawImage");
                }
                *got.entry(topics[i].topic()).or_insert(0) += 1;
            }
            2 => {
                let t = u64::from_le_bytes(b[1..9].try_into().expect("8 bytes"));
                assert!(t >= last_time, "time runs back: {t} after {last_time}");
                last_time = t;
                times += 1;
            }
            op => panic!("unknown server opcode {op}"),
        }
    }
    assert_eq!(got.len(), topics.len(), "got only {got:?}");
    assert!(times >= 2, "{times} time messages");
    // Publishing is refused, twice: the advertisement, then the message.
    let advertise = serde_json::json!({"op": "advertise", "channels": [
        {"id": 1, "topic": "/base/cmd", "encoding": "json", "schemaName": "x"}]});
    ws.send(Message::text(advertise.to_string()))
        .expect("sending advertise");
    ws.send(Message::binary(b"\x01\x01\x00\x00\x00{}".to_vec()))
        .expect("sending a message");
    let mut refusals = 0;
    while refusals < 2 {
        let status = read_json(&mut ws);
        if status["op"] == "status" {
            assert_eq!(status["level"], 2, "{status}");
            assert!(
                status["message"].as_str().unwrap_or("").contains("refused"),
                "{status}"
            );
            refusals += 1;
        }
    }
    let _ = ws.close(None);
    got
}

/// The final line's `key=value` fields.
fn done_line(path: &std::path::Path) -> BTreeMap<String, String> {
    let text = std::fs::read_to_string(path).expect("the recorder's output");
    let line = text
        .lines()
        .find(|l| l.starts_with("grop-recorder done"))
        .unwrap_or_else(|| panic!("no final line in {text}"));
    line.split_whitespace()
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_owned(), v.to_owned()))
        .collect()
}

#[test]
fn the_same_mission_twice_logs_the_same_messages_and_a_replay_reproduces_them() {
    let bins = mission::binaries(true).expect("the world and onboard binaries build");
    let mut specs = [logged_spec("log-a", 4), logged_spec("log-b", 4)];
    // The second serves the live view; its log must not change.
    specs[1].live = Some("127.0.0.1:0".parse().expect("address"));
    // Side by side: the two runs share the machine, which is the point.
    let mut running: Vec<_> = specs
        .iter()
        .map(|s| mission::start(s, &bins).expect("mission starts"))
        .collect();
    let addr = running[1]
        .live_addr(Duration::from_secs(60))
        .expect("the live view listens");
    // A client that subscribes to everything and never reads.
    let (release, stalled) = std::sync::mpsc::channel::<()>();
    let stalled = std::thread::spawn(move || {
        let mut ws = connect(addr);
        let (_, channels) = hello(&mut ws);
        let all: Vec<(u64, u64)> = channels.values().map(|id| (*id, *id)).collect();
        subscribe(&mut ws, &all);
        let _ = stalled.recv();
        drop(ws);
    });
    let viewer = std::thread::spawn(move || watch(addr));
    let reports: Vec<_> = running
        .into_iter()
        .map(|r| {
            r.finish(Duration::from_secs(600), &mut |_| {})
                .expect("the world reports")
        })
        .collect();
    let _ = release.send(());
    let got = viewer.join().expect("the viewer got what it subscribed to");
    stalled.join().expect("the stalled client");
    for r in &reports {
        assert_eq!(r.end, MissionEnd::Finished, "{:#?}", r.events);
    }
    let done = done_line(&specs[1].dir.join("recorder-out.log"));
    let count = |k: &str| -> u64 {
        done.get(k)
            .unwrap_or_else(|| panic!("no {k} in {done:?}"))
            .parse()
            .expect("a count")
    };
    eprintln!("live view: viewer got {got:?}; recorder: {done:?}");
    assert_eq!(count("dropped"), 0, "the log lost nothing");
    assert!(count("live_clients") >= 2);
    assert!(
        count("live_client_dropped") > 0,
        "the stalled client lost messages: {done:?}"
    );
    assert_eq!(count("live_refused"), 2, "the publish was refused");
    let logs: Vec<MissionLog> = specs
        .iter()
        .map(|s| MissionLog::read(s.log.as_deref().expect("logged")).expect("the log reads"))
        .collect();
    for log in &logs {
        assert!(log.truncated.is_none(), "{:?}", log.truncated);
        assert_eq!(log.unknown, 0);
        assert_eq!(log.log_format, grop_onboard::mission_log::LOG_FORMAT);
        for c in Channel::ALL {
            // These missions drive without the lidar (tests/common): no scan to log.
            if c == Channel::Scan && !specs[0].lidar {
                continue;
            }
            assert!(log.channel(c).count() > 0, "nothing on {}", c.topic());
        }
        // The channels in Foxglove's well-known schemas: every message has its schema's
        // fields and no other (the schema names and the JSON Schemas are advertised from the
        // same `Channel`, checked by the live viewer above).
        for c in Channel::VIEWS.into_iter().chain([Channel::Scan]) {
            for m in log.channel(c) {
                let v: serde_json::Value = serde_json::from_slice(&m.data).expect("JSON");
                if let Err(e) = grop_onboard::mission_log::foxglove::check(c.schema_name(), &v) {
                    panic!("{} at {} ns: {e}", c.topic(), m.log_time);
                }
            }
        }
        // Psi's views: one image for every heatmaps message (its frame was logged).
        assert_eq!(
            log.channel(Channel::PsiViews).count(),
            log.channel(Channel::Heatmaps).count()
        );
        // The world's truth is its own frame in /tf, near the estimate (map -> odom ->
        // base_link): within the localisation's error, not a mix-up of frames.
        let mut with_truth = 0;
        for m in log.channel(Channel::Tf) {
            let v: serde_json::Value = serde_json::from_slice(&m.data).expect("JSON");
            let planar = |child: &str| {
                v["transforms"]
                    .as_array()
                    .expect("transforms")
                    .iter()
                    .find(|t| t["child_frame_id"] == child)
                    .map(|t| {
                        let f = |a: &str, b: &str| t[a][b].as_f64().expect("a number");
                        let yaw = 2.0 * f("rotation", "z").atan2(f("rotation", "w"));
                        (f("translation", "x"), f("translation", "y"), yaw)
                    })
            };
            let (Some(truth), Some(odom), Some(base)) = (
                planar("truth_base_link"),
                planar("odom"),
                planar("base_link"),
            ) else {
                continue;
            };
            with_truth += 1;
            let x = odom.0 + odom.2.cos() * base.0 - odom.2.sin() * base.1;
            let y = odom.1 + odom.2.sin() * base.0 + odom.2.cos() * base.1;
            let off = (x - truth.0).hypot(y - truth.1);
            assert!(
                off < 0.5,
                "estimate {x:.3}, {y:.3} vs truth {truth:?} at {} ns",
                m.log_time
            );
        }
        assert!(with_truth > 0, "no truth frame in /tf");
        // Every plan's camera frame is in the log.
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
        .filter(|m| grop_onboard::mission_log::replay::compared(m))
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
        if grop_onboard::mission_log::replay::compared(m) {
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
