//! Seed inputs for every target: valid encodings made with the product's own encoders, the test
//! vectors of the crates' tests (reference §-numbers in comments), and the files in the
//! repository (scene, robot and deployment files, the ONNX models). `examples/seeds.rs` writes
//! them out; the fuzzer grows its corpus from them.

use std::path::Path;

use rmp_codec::RawFrame;
use rmp_codec::feedback::{FeedbackBitmaps, FeedbackItem, FeedbackLayout, FeedbackSet};
use rmp_codec::gen1::{Gen1Command, Gen1Config, Gen1Mode};
use rmp_codec::packet::{MAX_COMMAND_PACKET, encode_command};
use rmp_codec::v3::{
    ConfigCommand, EthernetField, FirmwareProfile, ModeRequest, MotionCommand, NvmFloat,
};
use ur5e::arm::ARM_OUTPUTS;
use ur5e::rtde::{RtdeType, RtdeValue, TextLevel, TextMessage};

use crate::ipc::bytes_of_message;

/// The repository root (this crate is `hil-tests/harnesses/fuzz-replay`).
fn repo_file(path: &str) -> Vec<u8> {
    let full = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../..")
        .join(path);
    match std::fs::read(&full) {
        Ok(bytes) => bytes,
        Err(e) => panic!("seed file {}: {e}", full.display()),
    }
}

/// A frame as the RMP targets read it: id (2 bytes), DLC, data.
fn frame_input(f: &RawFrame) -> Vec<u8> {
    let mut out = f.id().to_be_bytes().to_vec();
    out.push(f.len() as u8);
    out.extend_from_slice(f.data());
    out.resize(11, 0);
    out
}

fn frame(id: u16, data: &[u8]) -> RawFrame {
    match RawFrame::new(id, data) {
        Ok(f) => f,
        Err(e) => panic!("seed frame {id:#x}: {e}"),
    }
}

fn rmp_v3() -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    for (v, w) in [(0.5, 0.0), (-1.0, 1.0), (0.0, -0.25)] {
        if let Ok(m) = MotionCommand::new(v, w) {
            seeds.push(frame_input(&m.encode()));
        }
    }
    // NaN velocity and 2.0 yaw rate (the codec's own rejection tests).
    seeds.push(frame_input(&frame(0x500, &[0x7F, 0xC0, 0, 0, 0, 0, 0, 0])));
    seeds.push(frame_input(&frame(0x500, &[0, 0, 0, 0, 0x40, 0, 0, 0])));
    let commands = [
        ConfigCommand::None,
        ConfigCommand::SetFloat(NvmFloat::MaxVelocityMps, 1.2),
        ConfigCommand::SetFloat(NvmFloat::WheelBaseM, 0.6),
        ConfigCommand::SetInputConfigBitmap(0x0301),
        ConfigCommand::SetEthernet(EthernetField::Gateway, 0xC0A8_0001),
        ConfigCommand::SetFeedbackBitmap {
            index: 2,
            bitmap: 0x1234,
        },
        ConfigCommand::ForceConfigFeedback(true),
        ConfigCommand::Audio(16),
        ConfigCommand::SetOperationalMode(ModeRequest::Tractor),
        ConfigCommand::SendFaultLog(false),
        ConfigCommand::ResetIntegrators(0x1F),
        ConfigCommand::ResetParametersToDefault,
    ];
    for profile in [FirmwareProfile::SegwayInc2014, FirmwareProfile::Older440] {
        for c in commands {
            if let Ok(f) = c.encode(profile) {
                let mut input = frame_input(&f);
                if let Ok((command, parameter)) = c.to_words(profile) {
                    input.extend_from_slice(&command.to_be_bytes());
                    input.extend_from_slice(&parameter.to_be_bytes());
                }
                seeds.push(input);
            }
        }
    }
    seeds
}

fn rmp_gen1() -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    let commands = [
        (166, 0, None),
        (-1176, 1024, None),
        (0, 0, Some(Gen1Config::SetMode(Gen1Mode::Tractor))),
        (0, 0, Some(Gen1Config::ResetIntegrators(0x0F))),
        (10, -10, Some(Gen1Config::CurrentLimitScale(256))),
        (0, 0, Some(Gen1Config::BalanceLockout(true))),
    ];
    for (velocity_counts, turn_counts, config) in commands {
        let c = Gen1Command {
            velocity_counts,
            turn_counts,
            config,
        };
        if let Ok(f) = c.encode() {
            seeds.push(frame_input(&f));
        }
    }
    // ORCA CAN log frames (reference §1.2, §1.4).
    seeds.push(frame_input(&frame(
        0x403,
        &[0xBF, 0x8F, 0xFF, 0xFF, 0, 0, 0, 0],
    )));
    seeds.push(frame_input(&frame(
        0x406,
        &[0x00, 0x01, 0x00, 0x00, 0x01, 0x8D, 0x01, 0x30],
    )));
    seeds.push(frame_input(&frame(
        0x680,
        &[0x00, 0x05, 0x00, 0x80, 0x00, 0x00, 0x3E, 0x57],
    )));
    for id in 0x400..=0x407 {
        seeds.push(frame_input(&frame(id, &[1, 2, 3, 4, 5, 6, 7, 8])));
    }
    seeds
}

fn feedback_input(selector: u8, bitmaps: [u32; 3], frames: &[RawFrame]) -> Vec<u8> {
    let mut out = vec![selector];
    if selector & 1 == 0 {
        for b in bitmaps {
            out.extend_from_slice(&b.to_be_bytes());
        }
    }
    out.extend_from_slice(&[0, 0, 0, 0]);
    for f in frames {
        out.push(f.len() as u8);
        out.push((f.id() - 0x500) as u8);
        out.extend_from_slice(f.data());
    }
    out
}

fn rmp_feedback() -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    let sparse = FeedbackBitmaps::from_items(&[
        FeedbackItem::FaultStatusWord1,
        FeedbackItem::OperationalState,
        FeedbackItem::LinearVelocity,
        FeedbackItem::LinearPosition,
        FeedbackItem::FramVelocityLimit,
    ]);
    let driver = FeedbackBitmaps::from_items(&[
        FeedbackItem::FaultStatusWord1,
        FeedbackItem::FaultStatusWord2,
        FeedbackItem::FaultStatusWord3,
        FeedbackItem::FaultStatusWord4,
        FeedbackItem::OperationalState,
        FeedbackItem::LinearVelocity,
        FeedbackItem::DifferentialWheelVelocity,
        FeedbackItem::LinearPosition,
        FeedbackItem::InertialZRate,
    ]);
    for bitmaps in [FeedbackBitmaps::DEFAULT, sparse, driver] {
        let layout = FeedbackLayout::User(bitmaps);
        let set = FeedbackSet::from_fn(layout, |item| (item as u32) * 0x0101_0101);
        let frames: Vec<RawFrame> = set.frames().collect();
        let w = bitmaps.words();
        seeds.push(feedback_input(0, [w[0], w[1], w[2]], &frames));
        // Two sets back to back, the second cut short by a third.
        let mut twice = frames.clone();
        twice.extend_from_slice(&frames);
        twice.truncate(frames.len() + frames.len() / 2);
        twice.extend_from_slice(&frames);
        seeds.push(feedback_input(0, [w[0], w[1], w[2]], &twice));
    }
    let forced = FeedbackSet::from_fn(FeedbackLayout::ForcedConfig, |item| item as u32);
    let frames: Vec<RawFrame> = forced.frames().collect();
    seeds.push(feedback_input(1, [0; 3], &frames));
    seeds
}

fn rmp_packet() -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    // Reference §2.7 and §3.1 packets.
    let packets: [(u16, &[u32]); 5] = [
        (0x500, &[0x3F00_0000, 0]),
        (0x501, &[32, 5]),
        (0x501, &[0, 0]),
        (0x1800, &[0x3F00_0000, 0, 0x3E4C_CCCD]),
        (0x1803, &[6, 1]),
    ];
    for (id, words) in packets {
        let mut buf = [0u8; MAX_COMMAND_PACKET];
        if let Ok(n) = encode_command(id, words, &mut buf) {
            seeds.push(buf[..n].to_vec());
        }
    }
    seeds
}

/// The shared-memory bytes of a virtual-bus frame (`repr(C)`, native byte order).
fn wire_bytes(raw_id: u32, data: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&123_456_789u64.to_ne_bytes());
    out.extend_from_slice(&((7u64 << 32) | 1).to_ne_bytes());
    out.extend_from_slice(&42u64.to_ne_bytes());
    out.extend_from_slice(&raw_id.to_ne_bytes());
    out.push(data.len() as u8);
    let mut bytes = [0u8; 8];
    bytes[..data.len()].copy_from_slice(data);
    out.extend_from_slice(&bytes);
    out.extend_from_slice(&[0; 3]);
    out
}

fn can_wire_frame() -> Vec<Vec<u8>> {
    vec![
        wire_bytes(0x500, &[0x3F, 0, 0, 0, 0, 0, 0, 0]),
        wire_bytes(0x502, &[0, 0, 0, 4]),
        wire_bytes(0x8000_0413, &[]),
        wire_bytes(0x9FFF_FFFF, &[1, 2, 3, 4, 5, 6, 7, 8]),
        wire_bytes(0x800, &[]),
    ]
}

fn candump_text() -> Vec<Vec<u8>> {
    let mut seeds: Vec<Vec<u8>> = [
        "500#3F00000000000000",
        "501#0000002000000005",
        "502#DEAD",
        "00000413#",
        "1F334455#11",
        "7FF#0102030405060708",
        "vcan send hil 500#0000000100000000 00000413#",
        "(    1.234567) hil  502#0011223344556677",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect();
    // A dump of one default feedback set, as `vcan dump` prints it.
    let set = FeedbackSet::from_fn(FeedbackLayout::default(), |item| item as u32);
    let mut dump = String::new();
    for (k, f) in set.frames().take(8).enumerate() {
        let data: String = f.data().iter().map(|b| format!("{b:02X}")).collect();
        dump.push_str(&format!(
            "({:12.6}) hil  {:03X}#{data}\n",
            k as f64 * 0.02,
            f.id()
        ));
    }
    seeds.push(dump.into_bytes());
    seeds
}

fn package(ty: u8, payload: &[u8]) -> Vec<u8> {
    let mut out = ((payload.len() + 3) as u16).to_be_bytes().to_vec();
    out.push(ty);
    out.extend_from_slice(payload);
    out
}

fn text_package(message: &str, level: TextLevel) -> Vec<u8> {
    let mut payload = Vec::new();
    TextMessage {
        message: message.into(),
        source: "RTDE".into(),
        level,
    }
    .encode(&mut payload);
    package(b'M', &payload)
}

/// One data package of the arm's output recipe (id 7).
fn arm_data_package(t: f64) -> Vec<u8> {
    let mut payload = vec![7u8];
    for (k, (_, ty)) in ARM_OUTPUTS.iter().enumerate() {
        let value = match ty {
            RtdeType::Double => RtdeValue::Double(t),
            RtdeType::Vector6d => RtdeValue::Vector6d([t, -1.57, 1.57, -1.57, -1.57, k as f64]),
            RtdeType::Int32 => RtdeValue::Int32(7),
            RtdeType::Uint32 => RtdeValue::Uint32(2),
            other => RtdeValue::zero(*other),
        };
        value.encode(&mut payload);
    }
    package(b'U', &payload)
}

fn rtde_wire() -> Vec<Vec<u8>> {
    let mut seeds = vec![crate::rtde::canned_rtde_handshake()];
    let mut stream = arm_data_package(0.002);
    stream.extend(text_package("protective stop", TextLevel::Warning));
    stream.extend(package(
        b'v',
        &[0, 0, 0, 5, 0, 0, 0, 21, 0, 0, 0, 0, 0, 0, 0, 42],
    ));
    seeds.push(stream);
    // Recipe + fields (the field decoder's reading of the input).
    let mut fields = vec![10u8];
    fields.extend(0..10u8);
    for ty in RtdeType::ALL {
        RtdeValue::zero(ty).encode(&mut fields);
    }
    seeds.push(fields);
    seeds.push(package(b'O', b"\x07DOUBLE,VECTOR6D,NOT_FOUND,IN_USE,"));
    seeds
}

fn rtde_client() -> Vec<Vec<u8>> {
    let mut streaming = vec![1u8];
    for k in 0..3 {
        streaming.extend(arm_data_package(0.002 * f64::from(k)));
    }
    streaming.extend(text_package("hello", TextLevel::Info));
    streaming.extend(arm_data_package(0.008));
    let mut latest = streaming.clone();
    latest[0] = 3;
    let mut raw = vec![0u8];
    raw.extend(crate::rtde::canned_rtde_handshake());
    raw.extend(arm_data_package(0.0));
    let mut refused = vec![0u8];
    refused.extend(package(b'V', &[0]));
    let mut not_found = vec![0u8];
    not_found.extend(package(b'V', &[1]));
    not_found.extend(package(b'O', b"\x07NOT_FOUND"));
    vec![streaming, latest, raw, refused, not_found]
}

/// The socket seeds, and each again with packages split across reads of 1, 7 and 63 bytes.
fn rtde_stream() -> Vec<Vec<u8>> {
    let base = rtde_client();
    let mut seeds = base.clone();
    for cap in [1u8, 7, 63] {
        seeds.extend(base.iter().filter(|s| !s.is_empty()).map(|s| {
            let mut s = s.clone();
            s[0] = (s[0] & 3) | (cap << 2);
            s
        }));
    }
    seeds
}

fn dashboard_client() -> Vec<Vec<u8>> {
    let replies = "Robotmode: RUNNING\nSafetystatus: NORMAL\nSTOPPED grop.urp\n\
                   Program running: false\nfalse\nURSoftware 5.21.0.1210631 (Oct 23 2024)\n\
                   20205500123\nPowering on\nBrake releasing\nLoading program: grop.urp\n\
                   Starting program\nPausing program\nStopped\nProtective stop releasing\n\
                   closing safety popup\nPowering off\nRobotmode: IDLE\nDisconnected\n";
    let mut good = vec![1u8];
    good.extend_from_slice(replies.as_bytes());
    let mut welcome = vec![0u8];
    welcome.extend_from_slice(format!("{}\r\n", ur5e::dashboard::WELCOME).as_bytes());
    welcome.extend_from_slice(b"Robotmode: POWER_OFF\r\nSafetystatus: PROTECTIVE_STOP\r\n");
    vec![good, welcome, vec![0u8]]
}

fn gripper_client() -> Vec<Vec<u8>> {
    vec![
        // Already active; the move stops on an object; then status and a set.
        b"STA 3\nack\nPRE 255\nFLT 0\nOBJ 0\nFLT 0\nOBJ 2\nSTA 3\nSTA 3\nOBJ 2\nPOS 230\nFLT 0\nack\nPOS 0\n"
            .to_vec(),
        // Activation from reset, then a fault.
        b"STA 0\nack\nack\nFLT 0\nSTA 1\nFLT 0\nSTA 3\nack\nPRE 255\nFLT 7\n".to_vec(),
        b"?\n".to_vec(),
    ]
}

/// The socket seeds, and conversations with the script's markers (`scripted`): a reply
/// split across reads, a reply that times out and comes late on the old connection, a
/// reconnect (welcome again), a connection refused.
fn dashboard_replies() -> Vec<Vec<u8>> {
    let mut seeds = dashboard_client();
    let mut late = vec![1u8];
    late.extend_from_slice(b"Robotmode: RUN\xFDNING\nSafetys\xFEtatus: NORMAL\n\xFF");
    late.extend_from_slice(b"STOPPED grop.urp\nProgram running: false\n\xFEfalse\n\xFF");
    late.extend_from_slice(b"URSoftware 5.21.0.1210631 (Oct 23 2024)\n20205500123\n\xFE");
    seeds.push(late);
    seeds
}

/// As [`dashboard_replies`], for the gripper.
fn gripper_replies() -> Vec<Vec<u8>> {
    let mut seeds = gripper_client();
    seeds.push(
        b"STA 3\nack\nPRE 2\xFD55\nFLT 0\nOBJ 0\xFE\nFL\xFFT 0\nOBJ 2\nSTA \xFD3\nSTA 3\nOBJ 2\n\xFE\xFF"
            .to_vec(),
    );
    seeds
}

fn urscript() -> Vec<Vec<u8>> {
    let texts = [
        "def grop_motion():\n  rtde_set_watchdog(\"input_int_register_24\", 10, \"stop\")\n  \
         movej([0, -1.5, 1.25, -0.5, 0, 0.125], a=1.4, v=1.05)\nend\n",
        "movel(p[0.1, 0.2, 0.3, 0, 3.14, 0], 1.2, 0.25)\nstopj(2) # stop\n",
        "sec io():\n  set_standard_digital_out(3, True)\n  set_tool_digital_out(1, False)\n  \
         textmsg(\"a, b\", 2)\nend\n",
        "def s():\n  speedj([0.1, 0, 0, 0, 0, -0.1], 2.0, 0.5)\n  sleep(0.25)\n  sync()\n  \
         set_tcp(p[0, 0, 0.2, 0, 0, 0])\n  stopl(1.5)\nend\n",
    ];
    let mut seeds: Vec<Vec<u8>> = texts
        .iter()
        .map(|t| {
            let mut s = vec![0u8];
            s.extend_from_slice(t.as_bytes());
            s
        })
        .collect();
    // Writer programs: odd first byte, name byte, command count, commands.
    let mut written = vec![1u8, 1, 7];
    for kind in 0..7u8 {
        written.push(kind);
        written.extend_from_slice(&[0, 64, 0, 32, 0x80, 0x3F, 0xF0, 0, 0, 0, 0, 0, 1]);
        written.extend_from_slice(&[0, 16, 0, 8, 0, 4, 0, 2, 0, 1, 0, 3, 0, 5, 0, 6]);
    }
    seeds.push(written);
    seeds.push(vec![
        1, 1, 2, 7, 5, b'h', b'e', b'l', b'l', b'o', 8, 3, b'r', b'e', b'g', 0, 64, 2,
    ]);
    seeds
}

fn with_mode(mode: u8, text: &[u8]) -> Vec<u8> {
    let mut out = vec![mode];
    out.extend_from_slice(text);
    out
}

fn scene_file() -> Vec<Vec<u8>> {
    let example = repo_file("runtime/libraries/world/data/example-scene.toml");
    let mut seeds = vec![with_mode(0, &example)];
    // The same scene as the world writes it for a run (serde's layout, not the hand-written
    // one), and as JSON. Seeds never read a run's output folder: a clean checkout has none.
    if let Ok(scene) = world::Scene::from_toml_str(&String::from_utf8_lossy(&example), "x.toml") {
        if let Ok(toml) = scene.to_toml_string() {
            seeds.push(with_mode(0, toml.as_bytes()));
        }
        if let Ok(json) = scene.to_json_string() {
            seeds.push(with_mode(1, json.as_bytes()));
        }
    }
    seeds
}

/// A temporary file of its own for each call: the tests build the seeds on several threads at
/// once, and a file shared between them was written, read and removed under each other.
fn scratch_path(what: &str, extension: &str) -> std::path::PathBuf {
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    std::env::temp_dir().join(format!(
        "grop-seed-{what}-{}-{call}.{extension}",
        std::process::id()
    ))
}

fn robot_file() -> Vec<Vec<u8>> {
    let robot = repo_file("runtime/libraries/world/data/robot.toml");
    let mut seeds = vec![with_mode(0, &robot)];
    if let Ok(json) = world::RobotConfig::default().to_json_string() {
        seeds.push(with_mode(1, json.as_bytes()));
    }
    seeds
}

fn deployment_file() -> Vec<Vec<u8>> {
    let doc = "namespace = \"robot\"\nmap = \"scene.toml\"\nrobot = \"robot.toml\"\n\
               model = \"psi-fcn.onnx\"\ncan = \"socketcan:can0\"\nclock = \"wall\"\nseed = 42\n\
               lidar = \"udp:0.0.0.0:2368\"\n\n\
               [arm]\nhost = \"192.168.1.10\"\nrtde_port = 30004\ndashboard_port = 29999\n\
               script_port = 30002\ngripper_port = 63352\n\n[planner]\nmethod = \"grop\"\n\
               paper_smp = false\nretry = \"none\"\n";
    vec![
        repo_file("hil-tests/harnesses/fuzz-replay/data/hil-deployment.toml"),
        doc.as_bytes().to_vec(),
    ]
}

/// Logged messages of the channels with a decoder, as the recorder encodes them.
fn logged_messages() -> Vec<(grop_onboard::mission_log::Channel, Vec<u8>)> {
    use grop_ipc::{ArmIoMsg, BasePoseMsg, CameraFrameMsg, EventKind, EventMsg, HeartbeatMsg};
    use grop_onboard::mission_log::{Channel, codec};
    let mut out = Vec::new();
    let fix = BasePoseMsg::fix(
        3,
        123_456_789,
        grop_ipc::PoseFixKind::Global,
        [0.1, 2.0, 1.5],
        0.05,
        0.01,
    );
    out.push((Channel::BasePose, codec::encode_base_pose(&fix)));
    let io = ArmIoMsg {
        call: grop_ipc::ArmCall::Poll as u32,
        status: grop_ipc::ARM_STATUS_RUNNING,
        joints_rad: [0.0, -1.57, 1.57, -1.57, -1.57, 0.5],
        ..ArmIoMsg::default()
    };
    out.push((Channel::ArmIo, codec::encode_arm_io(&io)));
    let event = EventMsg::new(EventKind::GoalReached, 42, "goal 2 reached");
    out.push((Channel::Events, codec::encode_event(&event)));
    let beat = HeartbeatMsg {
        seq: 7,
        stamp_ns: 9_000,
        role: 2,
        pid: 0,
        overruns: 1,
    };
    out.push((Channel::Health, codec::encode_health(&beat)));
    if let Ok(f) = can_bus::CanFrame::new(
        can_bus::CanId::Standard(0x500),
        &[0x3F, 0, 0, 0, 0, 0, 0, 0],
    ) {
        out.push((Channel::Can, codec::encode_can(&f)));
    }
    let mut frame = CameraFrameMsg::boxed_zeroed();
    let mut header = frame.header;
    header.frame_id = 5;
    header.width_px = 4;
    header.height_px = 2;
    header.set_pixel_format(grop_ipc::PixelFormat::Mono8);
    header.row_stride_bytes = 4;
    header.metres_per_px = 0.5;
    let _ = frame.set_image(header, &[0, 50, 100, 150, 200, 250, 255, 1]);
    out.push((Channel::CameraFrame, codec::encode_camera(&frame)));
    out
}

fn mission_log() -> Vec<Vec<u8>> {
    use grop_onboard::mission_log::{Channel, LogWriter, WriterConfig};
    let messages = logged_messages();
    let mut seeds: Vec<Vec<u8>> = messages
        .iter()
        .map(|(channel, json)| {
            let index = Channel::ALL.iter().position(|c| c == channel).unwrap_or(0);
            let mut seed = vec![1u8, index as u8];
            seed.extend_from_slice(json);
            seed
        })
        .collect();
    // A whole log, as the recorder writes it.
    let path = scratch_path("log", "mcap");
    let mut metadata = std::collections::BTreeMap::new();
    metadata.insert(
        "grop.mission".to_owned(),
        [("seed".to_owned(), "1".to_owned())].into_iter().collect(),
    );
    if let Ok(writer) = LogWriter::create(&path, metadata, WriterConfig::default()) {
        for (k, (channel, json)) in messages.iter().enumerate() {
            writer.push(*channel, k as u64 * 1000, k as u64 * 1000, json.clone());
        }
        if writer.finish().is_ok()
            && let Ok(bytes) = std::fs::read(&path)
        {
            let mut seed = vec![0u8];
            seed.extend(bytes);
            seeds.push(seed);
        }
    }
    let _ = std::fs::remove_file(&path);
    seeds
}

fn ipc_messages() -> Vec<Vec<u8>> {
    (0..crate::ipc::MESSAGE_TYPES)
        .map(|which| {
            let mut out = vec![which];
            out.extend(bytes_of_message(which));
            out
        })
        .collect()
}

fn camera_frame() -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    // The paper's room at 640 x 480 RGB8 (3.125 cm per px), 64 x 64 Mono8 around a target,
    // 1280 x 960 RGB8 with a padded stride.
    let headers: [(u32, u32, u32, u32, f64, f64, f64); 3] = [
        (640, 480, 1, 1920, 0.03125, -10.0, 11.5),
        (64, 64, 2, 64, 0.0625, -2.0, 8.0),
        (1280, 960, 1, 3840, 0.015625, -10.0, 11.5),
    ];
    for (w, h, format, stride, m, left, top) in headers {
        for (x, fill, uniform) in [(0.0f64, 200u8, 1u8), (1.5, 0, 0), (-7.0, 128, 1)] {
            let mut out = Vec::new();
            out.extend_from_slice(&1u64.to_ne_bytes());
            out.extend_from_slice(&2u64.to_ne_bytes());
            for v in [w, h, format, stride] {
                out.extend_from_slice(&v.to_ne_bytes());
            }
            for v in [m, left, top] {
                out.extend_from_slice(&v.to_ne_bytes());
            }
            out.extend_from_slice(&x.to_be_bytes());
            out.push(fill);
            out.push(uniform);
            out.extend((0..64u8).map(|k| k.wrapping_mul(37)));
            seeds.push(out);
        }
    }
    seeds
}

/// Simulated VLP-16 packet streams (`vlp16::sim::Emitter` against a 3 m cylinder, a sector
/// without returns): across the azimuth wrap, in dual-return mode, with a foreign product id,
/// across the hourly timestamp wrap, and with a short and a malformed datagram among them.
fn vlp16_packet() -> Vec<Vec<u8>> {
    use vlp16::calib::Calibration;
    use vlp16::packet::ReturnMode;
    use vlp16::sim::Emitter;
    let stream = |config: u8, emitter: Result<Emitter, vlp16::sim::SimError>, packets: usize| {
        let mut emitter = match emitter {
            Ok(e) => e,
            Err(e) => panic!("seed emitter: {e}"),
        };
        // 1.33 ms between arrivals, in 10 us units.
        let mut input = vec![config, 0, 133];
        let mut sent = 0;
        let mut t_us = emitter.next_packet_time_us();
        while sent < packets {
            emitter.emit_until(
                t_us,
                &mut |f| {
                    let d = f.direction();
                    let horizontal = d[0].hypot(d[1]);
                    (f.azimuth_rad.abs() > 0.3).then(|| (3.0 / horizontal, 30 + f.laser))
                },
                &mut |bytes, _| {
                    if sent < packets {
                        input.extend_from_slice(bytes);
                        sent += 1;
                    }
                },
            );
            t_us += 1_000;
        }
        input
    };
    let c = Calibration::VLP16;
    let mut seeds = vec![
        stream(
            0,
            Emitter::new(600.0, ReturnMode::Strongest, c, 0)
                .map(|e| e.with_start_azimuth_deg(355.0)),
            3,
        ),
        stream(
            3,
            Emitter::new(600.0, ReturnMode::Dual, c, 0).map(|e| e.with_start_azimuth_deg(358.0)),
            3,
        ),
        stream(
            4,
            Emitter::new(1200.0, ReturnMode::Last, c, 0).map(|e| e.with_product_id(0x28)),
            2,
        ),
        stream(
            8,
            Emitter::new(1200.0, ReturnMode::Strongest, c, 3_599_998_000),
            2,
        ),
    ];
    let mut mixed = stream(0, Emitter::new(300.0, ReturnMode::Strongest, c, 10_000), 3);
    mixed[3 + 1206 + 700] = 0; // block 7's flag of the second packet
    mixed.extend_from_slice(&[0xFF, 0xEE, 0x10, 0x00]);
    seeds.push(mixed);
    seeds
}

fn model_loader() -> Vec<Vec<u8>> {
    [
        "models/fcn-infer/tests/fixtures/scale.onnx",
        "models/fcn-infer/tests/fixtures/float_input.onnx",
        "models/fcn-infer/tests/fixtures/wrong_output.onnx",
        "models/fcn-infer/tests/fixtures/wrong_shape.onnx",
        "models/fcn-infer/tests/fixtures/corrupt.onnx",
        "models/psi-fcn.onnx",
    ]
    .iter()
    .map(|p| repo_file(p))
    .collect()
}

/// Seeds per target, named as in [`crate::targets`].
pub fn seeds() -> Vec<(&'static str, Vec<Vec<u8>>)> {
    vec![
        ("rmp_v3", rmp_v3()),
        ("rmp_gen1", rmp_gen1()),
        ("rmp_feedback", rmp_feedback()),
        ("rmp_packet", rmp_packet()),
        ("can_wire_frame", can_wire_frame()),
        ("candump_text", candump_text()),
        ("rtde_wire", rtde_wire()),
        ("rtde_client", rtde_client()),
        ("rtde_stream", rtde_stream()),
        ("dashboard_client", dashboard_client()),
        ("dashboard_replies", dashboard_replies()),
        ("gripper_client", gripper_client()),
        ("gripper_replies", gripper_replies()),
        ("urscript", urscript()),
        ("scene_file", scene_file()),
        ("robot_file", robot_file()),
        ("deployment_file", deployment_file()),
        ("mission_log", mission_log()),
        ("mission_core", crate::mission_core::seeds()),
        ("ipc_messages", ipc_messages()),
        ("camera_frame", camera_frame()),
        ("model_loader", model_loader()),
        ("vlp16_packet", vlp16_packet()),
    ]
}
