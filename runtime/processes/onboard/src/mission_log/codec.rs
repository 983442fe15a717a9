//! How each message is written into the mission log: JSON, one schema per channel (JSON Schema;
//! the camera uses Foxglove's well-known `foxglove.RawImage`), so that Foxglove, the `mcap` CLI
//! or a ten-line Python script decode the log without our code. Encoding is lossless for every
//! field that describes behaviour (f64 and f32 print in their shortest round-trip form), so a
//! replay can turn the recorded inputs back into the exact messages. Two fields are left out
//! because they are not behaviour: a heartbeat's process id, and a plan's wall-clock decision
//! time, which goes to its own channel under `/timing/` (wall-clock measurements are never
//! deterministic; [`super::digest`] skips that prefix).

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use can_bus::{CanFrame, CanId};
use grop_ipc::{
    ArmIoMsg, ArmStateMsg, BasePoseMsg, BaseStateMsg, CameraFrameHeader, CameraFrameMsg, EventMsg,
    HEATMAP_COLS, HEATMAP_ROWS, HeartbeatMsg, HeatmapsMsg, LoadRequestMsg, MAX_HEATMAPS,
    MAX_TASK_STEPS, OperatorEnableMsg, ReplanRequestMsg, TaskPlanMsg, TruthMsg,
};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

/// Every channel of the log.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Channel {
    /// `camera/frame`, at the rate the recorder keeps (see the recorder's `--camera-period`).
    CameraFrame,
    /// `heatmaps`.
    Heatmaps,
    /// `plan/task`.
    TaskPlan,
    /// `plan/request`.
    PlanRequest,
    /// `base/pose` (localisation fixes).
    BasePose,
    /// `base/state`.
    BaseState,
    /// `arm/state`.
    ArmState,
    /// `arm/io` (every arm call and its answer).
    ArmIo,
    /// `events`.
    Events,
    /// `health`.
    Health,
    /// Every frame on the CAN bus.
    Can,
    /// Wall-clock decision time of each plan (not deterministic; not in the digest).
    DecisionTiming,
    /// `load/request` (the objects the executive asks the station to put on the tray).
    LoadRequest,
    /// `operator/enable` (the operator's enable; since `log_format` 3).
    OperatorEnable,
    /// `/tf`: the frames (`foxglove.FrameTransforms`; a view, since `log_format` 4).
    Tf,
    /// `/scene`: the room, furniture, targets, tray (`foxglove.SceneUpdate`; a view, since 4).
    Scene,
    /// `/plan/path`: the plan's route (`foxglove.PosesInFrame`; a view, since 4).
    PlannedPath,
    /// `/base/path`: the route driven so far (`foxglove.PosesInFrame`; a view, since 4).
    DrivenPath,
    /// `/heatmaps/grid`: Psi's heatmaps over the floor (`foxglove.Grid`; a view, since 4).
    HeatmapGrid,
    /// `/events/log`: the events as log messages (`foxglove.Log`; a view, since 4).
    EventLog,
    /// `/scan`: the range sensor's revolutions as the executive's collision monitor took them,
    /// one per second (`foxglove.PointCloud` in `base_link`; since 4).
    Scan,
    /// `/world/truth`: where the simulated world's base really is (HIL only; the recorder logs
    /// it, nothing onboard reads it; since `log_format` 5).
    Truth,
    /// `/psi/views`: the crops Psi saw for a decision beside its heatmaps, one row a location
    /// (`foxglove.RawImage`; a view, since 5).
    PsiViews,
}

impl Channel {
    /// All channels, in channel-id order.
    pub const ALL: [Channel; 23] = [
        Channel::CameraFrame,
        Channel::Heatmaps,
        Channel::TaskPlan,
        Channel::PlanRequest,
        Channel::BasePose,
        Channel::BaseState,
        Channel::ArmState,
        Channel::ArmIo,
        Channel::Events,
        Channel::Health,
        Channel::Can,
        Channel::DecisionTiming,
        Channel::LoadRequest,
        Channel::OperatorEnable,
        Channel::Tf,
        Channel::Scene,
        Channel::PlannedPath,
        Channel::DrivenPath,
        Channel::HeatmapGrid,
        Channel::EventLog,
        Channel::Scan,
        Channel::Truth,
        Channel::PsiViews,
    ];

    /// The channels in Foxglove's well-known schemas that the recorder derives from the others
    /// (`super::views`): a replay compares the messages they come from, not them.
    pub const VIEWS: [Channel; 7] = [
        Channel::Tf,
        Channel::Scene,
        Channel::PlannedPath,
        Channel::DrivenPath,
        Channel::HeatmapGrid,
        Channel::EventLog,
        Channel::PsiViews,
    ];

    /// Whether the recorder derives this channel from the others (see [`Channel::VIEWS`]).
    pub fn is_view(self) -> bool {
        Channel::VIEWS.contains(&self)
    }

    /// The MCAP topic.
    pub fn topic(self) -> &'static str {
        match self {
            Channel::CameraFrame => "/camera/frame",
            Channel::Heatmaps => "/heatmaps",
            Channel::TaskPlan => "/plan/task",
            Channel::PlanRequest => "/plan/request",
            Channel::BasePose => "/base/pose",
            Channel::BaseState => "/base/state",
            Channel::ArmState => "/arm/state",
            Channel::ArmIo => "/arm/io",
            Channel::Events => "/events",
            Channel::Health => "/health",
            Channel::Can => "/can",
            Channel::DecisionTiming => "/timing/decision",
            Channel::LoadRequest => "/load/request",
            Channel::OperatorEnable => "/operator/enable",
            Channel::Tf => "/tf",
            Channel::Scene => "/scene",
            Channel::PlannedPath => "/plan/path",
            Channel::DrivenPath => "/base/path",
            Channel::HeatmapGrid => "/heatmaps/grid",
            Channel::EventLog => "/events/log",
            Channel::Scan => "/scan",
            Channel::Truth => "/world/truth",
            Channel::PsiViews => "/psi/views",
        }
    }

    /// The channel of an MCAP topic.
    pub fn from_topic(topic: &str) -> Option<Channel> {
        Channel::ALL.into_iter().find(|c| c.topic() == topic)
    }

    /// The schema's name.
    pub fn schema_name(self) -> &'static str {
        match self {
            Channel::CameraFrame | Channel::PsiViews => "foxglove.RawImage",
            Channel::Heatmaps => "grop.Heatmaps",
            Channel::TaskPlan => "grop.TaskPlan",
            Channel::PlanRequest => "grop.ReplanRequest",
            Channel::BasePose => "grop.BasePoseFix",
            Channel::BaseState => "grop.BaseState",
            Channel::ArmState => "grop.ArmState",
            Channel::ArmIo => "grop.ArmIo",
            Channel::Events => "grop.Event",
            Channel::Health => "grop.Heartbeat",
            Channel::Can => "grop.CanFrame",
            Channel::DecisionTiming => "grop.DecisionTiming",
            Channel::LoadRequest => "grop.LoadRequest",
            Channel::OperatorEnable => "grop.OperatorEnable",
            Channel::Tf => "foxglove.FrameTransforms",
            Channel::Scene => "foxglove.SceneUpdate",
            Channel::PlannedPath | Channel::DrivenPath => "foxglove.PosesInFrame",
            Channel::HeatmapGrid => "foxglove.Grid",
            Channel::EventLog => "foxglove.Log",
            Channel::Scan => "foxglove.PointCloud",
            Channel::Truth => "grop.Truth",
        }
    }

    /// The channel's JSON Schema.
    #[allow(
        clippy::too_many_lines,
        reason = "one JSON schema per logged message kind"
    )]
    pub fn schema(self) -> Value {
        let num = json!({"type": "number"});
        let int = json!({"type": "integer"});
        let text = json!({"type": "string"});
        let nums = |n: usize| json!({"type": "array", "items": {"type": "number"}, "minItems": n, "maxItems": n});
        let (title, properties): (&str, Value) = match self {
            Channel::CameraFrame => (
                "An overhead camera frame (Foxglove RawImage) with where it lies on the floor",
                json!({
                    "timestamp": {"type": "object", "properties": {"sec": int, "nsec": int}},
                    "frame_id": text, "width": int, "height": int,
                    "encoding": {"type": "string", "enum": ["rgb8", "mono8"]},
                    "step": int,
                    "data": {"type": "string", "contentEncoding": "base64"},
                    "grop_frame_id": int, "metres_per_px": num, "left_x_m": num, "top_y_m": num
                }),
            ),
            Channel::Heatmaps => (
                "Psi's predicted unloading success per cell, one heatmap per location",
                json!({
                    "stamp_ns": int, "source_frame_id": int, "rows": int, "cols": int,
                    "locations": {"type": "array", "items": {"type": "object", "properties": {
                        "object": int, "side": int, "target_m": nums(3), "feasibility": num,
                        "values": {"type": "array", "items": {"type": "number"},
                                   "description": "rows x cols, row-major"}
                    }}}
                }),
            ),
            Channel::TaskPlan => (
                "A task plan (GROP's decision): navigate, load and unload steps",
                json!({
                    "plan_id": int, "stamp_ns": int, "source_frame_id": int,
                    "answers_request": int, "utility": num, "feasibility": num, "cost_s": num,
                    "reward": num, "object_count": int,
                    "steps": {"type": "array", "items": {"type": "object", "properties": {
                        "kind": int, "kind_name": text, "side": int, "object": int,
                        "load_mask": int, "x_m": num, "y_m": num, "yaw_rad": num,
                        "target_m": nums(3), "feasibility": num, "travel_cost_s": num,
                        "approach_m": num, "back_out_m": num,
                        "tray_slot": {"type": "integer",
                                      "description": "unload: its slot; load: the slots it fills (bit mask)"}
                    }}}
                }),
            ),
            Channel::PlanRequest => (
                "The executive asks for a (new) plan",
                json!({
                    "request_id": int, "stamp_ns": int, "reason": int, "reason_name": text,
                    "failed_object": int, "remaining_mask": int, "on_board_mask": int,
                    "pose": nums(3), "failed_side": int, "failed_goal_m": nums(2),
                    "flags": {"type": "integer", "description": "bit 0: the base stands at a table"},
                    "tray": {"type": "array", "items": {"type": "integer"},
                             "description": "per slot, the object in it plus one (0: empty)"}
                }),
            ),
            Channel::LoadRequest => (
                "The executive asks the loading station for objects on the tray",
                json!({
                    "request_id": int, "stamp_ns": int, "plan_id": int, "step_index": int,
                    "object_mask": int, "station_m": nums(2),
                    "slots": {"type": "array", "items": {"type": "integer"},
                              "description": "per slot, the object to put in it plus one"}
                }),
            ),
            Channel::OperatorEnable => (
                "The operator's enable (arms the robot; releases a latched stop)",
                json!({"seq": int, "stamp_ns": int}),
            ),
            Channel::BasePose => (
                "A localisation fix of the base",
                json!({
                    "seq": int, "stamp_ns": int, "kind": int, "kind_name": text,
                    "x_m": num, "y_m": num, "yaw_rad": num, "sigma_xy_m": num,
                    "sigma_yaw_rad": num
                }),
            ),
            Channel::BaseState => (
                "The base as the executive sees it",
                json!({
                    "seq": int, "stamp_ns": int, "x_m": num, "y_m": num, "yaw_rad": num,
                    "speed_mps": num, "yaw_rate_radps": num, "commanded_speed_mps": num,
                    "commanded_yaw_rate_radps": num, "mode": int, "mode_name": text,
                    "fault_bits": int, "link_up": int, "watchdog_stopped": int,
                    "monitor": {"type": "integer",
                                "description": "the collision monitor: 0 off (no sensor), 1 clear, 2 crawl, 3 slowdown, 4 approach, 5 stop, 6 stale"},
                    "monitor_name": text,
                    "monitor_clearance_m": {"type": ["number", "null"],
                                            "description": "footprint to the nearest point, to the cm (null: none seen, or no sensor)"}
                }),
            ),
            Channel::ArmState => (
                "The arm as the executive sees it",
                json!({
                    "seq": int, "stamp_ns": int, "joints_rad": nums(6),
                    "joint_speeds_radps": nums(6), "flange_pose": nums(6),
                    "gripper_opening_m": num, "safety": int, "safety_name": text,
                    "robot_mode": int, "program_running": int, "connected": int,
                    "object_held": int
                }),
            ),
            Channel::ArmIo => (
                "One call of the executive on the arm and its answer",
                json!({
                    "seq": int, "stamp_ns": int, "call": int, "call_name": text,
                    "outcome": int, "status": int, "flags": int, "robot_mode": int,
                    "joints_rad": nums(6), "joint_speeds_radps": nums(6), "flange_pose": nums(6)
                }),
            ),
            Channel::Events => (
                "Mission events",
                json!({
                    "seq": int, "stamp_ns": int, "plan_id": int, "kind": int,
                    "kind_name": text, "step_index": int, "detail": text,
                    "source": {"type": "integer", "description": "1 planner, 2 executive, 3 world, 0 unsaid"}
                }),
            ),
            Channel::Health => (
                "A process is alive",
                json!({
                    "seq": int, "stamp_ns": int, "role": int, "role_name": text,
                    "overruns": int
                }),
            ),
            Channel::Can => (
                "A CAN frame on the base's bus",
                json!({
                    "id": int, "extended": {"type": "boolean"},
                    "data": {"type": "array", "items": {"type": "integer"}, "maxItems": 8}
                }),
            ),
            Channel::Truth => (
                "Where the simulated world's base really is (HIL only; read by nothing onboard)",
                json!({
                    "seq": int, "stamp_ns": int, "x_m": num, "y_m": num, "yaw_rad": num,
                    "speed_mps": num, "yaw_rate_radps": num
                }),
            ),
            Channel::DecisionTiming => (
                "Wall-clock time the planner took for a plan (a measurement, not behaviour)",
                json!({"plan_id": int, "decision_us": int}),
            ),
            Channel::Tf
            | Channel::Scene
            | Channel::PlannedPath
            | Channel::DrivenPath
            | Channel::HeatmapGrid
            | Channel::EventLog
            | Channel::Scan
            | Channel::PsiViews => return super::foxglove::json_schema(self.schema_name()),
        };
        json!({
            "$schema": "https://json-schema.org/draft/2020-12/schema",
            "title": title,
            "type": "object",
            "properties": properties,
        })
    }
}

/// Why a logged message could not be turned back into a message.
#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
    /// Not the JSON of the channel's schema.
    #[error("{channel}: not a valid {schema} message: {source}")]
    Json {
        /// Topic.
        channel: &'static str,
        /// Schema name.
        schema: &'static str,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// JSON fine, content not.
    #[error("{channel}: {detail}")]
    Content {
        /// Topic.
        channel: &'static str,
        /// What was wrong.
        detail: String,
    },
}

fn parse<'a, T: Deserialize<'a>>(channel: Channel, data: &'a [u8]) -> Result<T, DecodeError> {
    serde_json::from_slice(data).map_err(|source| DecodeError::Json {
        channel: channel.topic(),
        schema: channel.schema_name(),
        source,
    })
}

fn to_vec<T: Serialize>(value: &T) -> Vec<u8> {
    // Serialising plain structs of numbers and strings into a Vec cannot fail.
    serde_json::to_vec(value).unwrap_or_default()
}

fn name<T: std::fmt::Debug, E>(r: Result<T, E>) -> String {
    match r {
        Ok(v) => format!("{v:?}"),
        Err(_) => "invalid".to_owned(),
    }
}

#[derive(Serialize, Deserialize)]
struct Stamp {
    sec: u64,
    nsec: u32,
}

#[derive(Serialize, Deserialize)]
struct RawImage {
    timestamp: Stamp,
    frame_id: String,
    width: u32,
    height: u32,
    encoding: String,
    step: u32,
    data: String,
    grop_frame_id: u64,
    metres_per_px: f64,
    left_x_m: f64,
    top_y_m: f64,
}

/// A range sensor's revolution as a `foxglove.PointCloud` in `base_link`: x, y, z float32 per
/// point (z 0.1 m: the points lie on the floor plane, drawn just above it).
pub fn encode_scan(m: &grop_ipc::ScanMsg) -> Vec<u8> {
    use super::foxglove::{FLOAT32, PackedElementField, PointCloud, Pose, Time};
    let mut data = Vec::with_capacity(grop_ipc::SCAN_BINS * 12);
    for [x, y] in m.points() {
        for v in [x, y, 0.1f32] {
            data.extend_from_slice(&v.to_le_bytes());
        }
    }
    let field = |name: &str, offset: u32| PackedElementField {
        name: name.to_owned(),
        offset,
        kind: FLOAT32,
    };
    to_vec(&PointCloud {
        timestamp: Time::from_ns(m.stamp_ns),
        frame_id: "base_link".to_owned(),
        pose: Pose::default(),
        point_stride: 12,
        fields: vec![field("x", 0), field("y", 4), field("z", 8)],
        data: BASE64.encode(&data),
    })
}

/// A camera frame (its checked image only).
pub fn encode_camera(m: &CameraFrameMsg) -> Vec<u8> {
    let h = &m.header;
    let (encoding, data) = match (h.pixel_format(), m.image()) {
        (Ok(grop_ipc::PixelFormat::Mono8), Ok(img)) => ("mono8", BASE64.encode(img)),
        (Ok(_), Ok(img)) => ("rgb8", BASE64.encode(img)),
        _ => ("rgb8", String::new()),
    };
    to_vec(&RawImage {
        timestamp: Stamp {
            sec: h.stamp_ns / 1_000_000_000,
            nsec: (h.stamp_ns % 1_000_000_000) as u32,
        },
        frame_id: "overhead".to_owned(),
        width: h.width_px,
        height: h.height_px,
        encoding: encoding.to_owned(),
        step: h.row_stride_bytes,
        data,
        grop_frame_id: h.frame_id,
        metres_per_px: h.metres_per_px,
        left_x_m: h.left_x_m,
        top_y_m: h.top_y_m,
    })
}

/// The frame id a logged camera frame carries (to match plans to their frame).
pub fn camera_frame_id(data: &[u8]) -> Result<u64, DecodeError> {
    #[derive(Deserialize)]
    struct Id {
        grop_frame_id: u64,
    }
    Ok(parse::<Id>(Channel::CameraFrame, data)?.grop_frame_id)
}

/// Writes a logged camera frame into `out` (a loaned message), header checked.
pub fn decode_camera_into(data: &[u8], out: &mut CameraFrameMsg) -> Result<(), DecodeError> {
    let c = Channel::CameraFrame;
    let raw: RawImage = parse(c, data)?;
    let format = match raw.encoding.as_str() {
        "rgb8" => grop_ipc::PixelFormat::Rgb8,
        "mono8" => grop_ipc::PixelFormat::Mono8,
        other => {
            return Err(DecodeError::Content {
                channel: c.topic(),
                detail: format!("encoding {other:?} (expected rgb8 or mono8)"),
            });
        }
    };
    let mut header = CameraFrameHeader {
        frame_id: raw.grop_frame_id,
        stamp_ns: raw.timestamp.sec * 1_000_000_000 + u64::from(raw.timestamp.nsec),
        width_px: raw.width,
        height_px: raw.height,
        pixel_format: 0,
        row_stride_bytes: raw.step,
        metres_per_px: raw.metres_per_px,
        left_x_m: raw.left_x_m,
        top_y_m: raw.top_y_m,
    };
    header.set_pixel_format(format);
    let pixels = BASE64
        .decode(raw.data.as_bytes())
        .map_err(|e| DecodeError::Content {
            channel: c.topic(),
            detail: format!("data is not base64: {e}"),
        })?;
    out.set_image(header, &pixels)
        .map_err(|e| DecodeError::Content {
            channel: c.topic(),
            detail: e.to_string(),
        })
}

#[derive(Serialize)]
struct HeatmapJson<'a> {
    object: u32,
    side: i32,
    target_m: [f64; 3],
    feasibility: f64,
    values: &'a [f32],
}

#[derive(Serialize)]
struct HeatmapsJson<'a> {
    stamp_ns: u64,
    source_frame_id: u64,
    rows: usize,
    cols: usize,
    locations: Vec<HeatmapJson<'a>>,
}

/// Heatmaps (the valid locations only).
pub fn encode_heatmaps(m: &HeatmapsMsg) -> Vec<u8> {
    let n = (m.count as usize).min(MAX_HEATMAPS);
    to_vec(&HeatmapsJson {
        stamp_ns: m.stamp_ns,
        source_frame_id: m.source_frame_id,
        rows: HEATMAP_ROWS,
        cols: HEATMAP_COLS,
        locations: m.locations[..n]
            .iter()
            .map(|l| HeatmapJson {
                object: l.object_index,
                side: l.side,
                target_m: l.target_m,
                feasibility: l.feasibility,
                values: &l.values,
            })
            .collect(),
    })
}

#[derive(Serialize)]
struct StepJson {
    kind: u32,
    kind_name: String,
    side: i32,
    object: u32,
    load_mask: u64,
    x_m: f64,
    y_m: f64,
    yaw_rad: f64,
    target_m: [f64; 3],
    feasibility: f64,
    travel_cost_s: f64,
    approach_m: f64,
    back_out_m: f64,
    tray_slot: u32,
}

#[derive(Serialize)]
struct TaskPlanJson {
    plan_id: u64,
    stamp_ns: u64,
    source_frame_id: u64,
    answers_request: u64,
    utility: f64,
    feasibility: f64,
    cost_s: f64,
    reward: f64,
    object_count: u32,
    steps: Vec<StepJson>,
}

/// A task plan (its steps, without the wall-clock decision time: see [`encode_decision_timing`]).
pub fn encode_task_plan(m: &TaskPlanMsg) -> Vec<u8> {
    let n = (m.step_count as usize).min(MAX_TASK_STEPS);
    to_vec(&TaskPlanJson {
        plan_id: m.plan_id,
        stamp_ns: m.stamp_ns,
        source_frame_id: m.source_frame_id,
        answers_request: m.answers_request,
        utility: m.utility,
        feasibility: m.feasibility,
        cost_s: m.cost_s,
        reward: m.reward,
        object_count: m.object_count,
        steps: m.steps[..n]
            .iter()
            .map(|s| StepJson {
                kind: s.kind,
                kind_name: name(s.kind()),
                side: s.side,
                object: s.object_index,
                load_mask: s.load_mask,
                x_m: s.x_m,
                y_m: s.y_m,
                yaw_rad: s.yaw_rad,
                target_m: s.target_m,
                feasibility: s.feasibility,
                travel_cost_s: s.travel_cost_s,
                approach_m: s.approach_m,
                back_out_m: s.back_out_m,
                tray_slot: s.tray_slot,
            })
            .collect(),
    })
}

/// The wall-clock decision time of a plan.
pub fn encode_decision_timing(m: &TaskPlanMsg) -> Vec<u8> {
    to_vec(&json!({"plan_id": m.plan_id, "decision_us": m.decision_us}))
}

/// A replan request.
pub fn encode_plan_request(m: &ReplanRequestMsg) -> Vec<u8> {
    to_vec(&json!({
        "request_id": m.request_id, "stamp_ns": m.stamp_ns, "reason": m.reason,
        "reason_name": name(m.reason()), "failed_object": m.failed_object,
        "remaining_mask": m.remaining_mask, "on_board_mask": m.on_board_mask, "pose": m.pose,
        "failed_side": m.failed_side, "failed_goal_m": m.failed_goal_m, "flags": m.flags,
        "tray": m.tray
    }))
}

/// A load request.
pub fn encode_load_request(m: &LoadRequestMsg) -> Vec<u8> {
    to_vec(&json!({
        "request_id": m.request_id, "stamp_ns": m.stamp_ns, "plan_id": m.plan_id,
        "step_index": m.step_index, "object_mask": m.object_mask, "station_m": m.station_m,
        "slots": m.slots
    }))
}

#[derive(Serialize, Deserialize)]
struct BasePoseJson {
    seq: u64,
    stamp_ns: u64,
    kind: u32,
    kind_name: String,
    x_m: f64,
    y_m: f64,
    yaw_rad: f64,
    sigma_xy_m: f64,
    sigma_yaw_rad: f64,
}

#[derive(Serialize, Deserialize)]
struct TruthJson {
    seq: u64,
    stamp_ns: u64,
    x_m: f64,
    y_m: f64,
    yaw_rad: f64,
    speed_mps: f64,
    yaw_rate_radps: f64,
}

/// The simulated world's truth.
pub fn encode_truth(m: &TruthMsg) -> Vec<u8> {
    to_vec(&TruthJson {
        seq: m.seq,
        stamp_ns: m.stamp_ns,
        x_m: m.x_m,
        y_m: m.y_m,
        yaw_rad: m.yaw_rad,
        speed_mps: m.speed_mps,
        yaw_rate_radps: m.yaw_rate_radps,
    })
}

/// A logged truth, back as the message.
pub fn decode_truth(data: &[u8]) -> Result<TruthMsg, DecodeError> {
    let j: TruthJson = parse(Channel::Truth, data)?;
    Ok(TruthMsg {
        seq: j.seq,
        stamp_ns: j.stamp_ns,
        x_m: j.x_m,
        y_m: j.y_m,
        yaw_rad: j.yaw_rad,
        speed_mps: j.speed_mps,
        yaw_rate_radps: j.yaw_rate_radps,
    })
}

/// A localisation fix.
pub fn encode_base_pose(m: &BasePoseMsg) -> Vec<u8> {
    to_vec(&BasePoseJson {
        seq: m.seq,
        stamp_ns: m.stamp_ns,
        kind: m.kind,
        kind_name: name(m.kind()),
        x_m: m.x_m,
        y_m: m.y_m,
        yaw_rad: m.yaw_rad,
        sigma_xy_m: m.sigma_xy_m,
        sigma_yaw_rad: m.sigma_yaw_rad,
    })
}

/// A logged localisation fix, back as the message.
pub fn decode_base_pose(data: &[u8]) -> Result<BasePoseMsg, DecodeError> {
    let j: BasePoseJson = parse(Channel::BasePose, data)?;
    Ok(BasePoseMsg {
        seq: j.seq,
        stamp_ns: j.stamp_ns,
        kind: j.kind,
        reserved: 0,
        x_m: j.x_m,
        y_m: j.y_m,
        yaw_rad: j.yaw_rad,
        sigma_xy_m: j.sigma_xy_m,
        sigma_yaw_rad: j.sigma_yaw_rad,
    })
}

/// The base state.
pub fn encode_base_state(m: &BaseStateMsg) -> Vec<u8> {
    to_vec(&json!({
        "seq": m.seq, "stamp_ns": m.stamp_ns, "x_m": m.x_m, "y_m": m.y_m,
        "yaw_rad": m.yaw_rad, "speed_mps": m.speed_mps, "yaw_rate_radps": m.yaw_rate_radps,
        "commanded_speed_mps": m.commanded_speed_mps,
        "commanded_yaw_rate_radps": m.commanded_yaw_rate_radps, "mode": m.mode,
        "mode_name": name(m.mode()), "fault_bits": m.fault_bits, "link_up": m.link_up,
        "watchdog_stopped": m.watchdog_stopped, "monitor": m.monitor,
        "monitor_name": name(m.monitor()),
        "monitor_clearance_m": (m.monitor_clearance_cm != grop_ipc::NO_CLEARANCE_CM)
            .then(|| f64::from(m.monitor_clearance_cm) / 100.0)
    }))
}

/// The arm state.
pub fn encode_arm_state(m: &ArmStateMsg) -> Vec<u8> {
    to_vec(&json!({
        "seq": m.seq, "stamp_ns": m.stamp_ns, "joints_rad": m.joints_rad,
        "joint_speeds_radps": m.joint_speeds_radps, "flange_pose": m.flange_pose,
        "gripper_opening_m": m.gripper_opening_m, "safety": m.safety,
        "safety_name": name(m.safety()), "robot_mode": m.robot_mode,
        "program_running": m.program_running, "connected": m.connected,
        "object_held": m.object_held
    }))
}

#[derive(Serialize, Deserialize)]
struct ArmIoJson {
    seq: u64,
    stamp_ns: u64,
    call: u32,
    call_name: String,
    outcome: u32,
    status: u32,
    flags: u32,
    robot_mode: i32,
    joints_rad: [f64; 6],
    joint_speeds_radps: [f64; 6],
    flange_pose: [f64; 6],
}

/// An arm call.
pub fn encode_arm_io(m: &ArmIoMsg) -> Vec<u8> {
    to_vec(&ArmIoJson {
        seq: m.seq,
        stamp_ns: m.stamp_ns,
        call: m.call,
        call_name: name(m.call()),
        outcome: m.outcome,
        status: m.status,
        flags: m.flags,
        robot_mode: m.robot_mode,
        joints_rad: m.joints_rad,
        joint_speeds_radps: m.joint_speeds_radps,
        flange_pose: m.flange_pose,
    })
}

/// A logged arm call, back as the message (enums checked).
pub fn decode_arm_io(data: &[u8]) -> Result<ArmIoMsg, DecodeError> {
    let j: ArmIoJson = parse(Channel::ArmIo, data)?;
    let m = ArmIoMsg {
        seq: j.seq,
        stamp_ns: j.stamp_ns,
        call: j.call,
        outcome: j.outcome,
        status: j.status,
        flags: j.flags,
        robot_mode: j.robot_mode,
        reserved: 0,
        joints_rad: j.joints_rad,
        joint_speeds_radps: j.joint_speeds_radps,
        flange_pose: j.flange_pose,
    };
    let content = |e: grop_ipc::MessageError| DecodeError::Content {
        channel: Channel::ArmIo.topic(),
        detail: e.to_string(),
    };
    m.call().map_err(content)?;
    m.outcome().map_err(content)?;
    Ok(m)
}

#[derive(Serialize, Deserialize)]
struct EventJson {
    seq: u64,
    stamp_ns: u64,
    plan_id: u64,
    kind: u32,
    kind_name: String,
    step_index: u32,
    source: u32,
    detail: String,
}

/// An event.
pub fn encode_event(m: &EventMsg) -> Vec<u8> {
    to_vec(&EventJson {
        seq: m.seq,
        stamp_ns: m.stamp_ns,
        plan_id: m.plan_id,
        kind: m.kind,
        kind_name: name(m.kind()),
        step_index: m.step_index,
        source: m.source,
        detail: m.detail().unwrap_or("<invalid utf-8>").to_owned(),
    })
}

/// A logged event, back as the message (kind checked).
pub fn decode_event(data: &[u8]) -> Result<EventMsg, DecodeError> {
    let j: EventJson = parse(Channel::Events, data)?;
    let mut m = EventMsg::new(grop_ipc::EventKind::PlanStarted, j.stamp_ns, &j.detail);
    m.kind = j.kind;
    m.kind().map_err(|e| DecodeError::Content {
        channel: Channel::Events.topic(),
        detail: e.to_string(),
    })?;
    m.seq = j.seq;
    m.plan_id = j.plan_id;
    m.step_index = j.step_index;
    m.source = j.source;
    Ok(m)
}

#[derive(Serialize, Deserialize)]
struct HeartbeatJson {
    seq: u64,
    stamp_ns: u64,
    role: u32,
    role_name: String,
    overruns: u64,
}

/// A heartbeat (without the process id, which differs run to run).
pub fn encode_health(m: &HeartbeatMsg) -> Vec<u8> {
    to_vec(&HeartbeatJson {
        seq: m.seq,
        stamp_ns: m.stamp_ns,
        role: m.role,
        role_name: name(m.role()),
        overruns: m.overruns,
    })
}

/// A logged heartbeat, back as the message (process id 0).
pub fn decode_health(data: &[u8]) -> Result<HeartbeatMsg, DecodeError> {
    let j: HeartbeatJson = parse(Channel::Health, data)?;
    Ok(HeartbeatMsg {
        seq: j.seq,
        stamp_ns: j.stamp_ns,
        role: j.role,
        pid: 0,
        overruns: j.overruns,
    })
}

#[derive(Serialize, Deserialize)]
struct EnableJson {
    seq: u64,
    stamp_ns: u64,
}

/// An operator's enable (without the process id, which differs run to run).
pub fn encode_enable(m: &OperatorEnableMsg) -> Vec<u8> {
    to_vec(&EnableJson {
        seq: m.seq,
        stamp_ns: m.stamp_ns,
    })
}

/// A logged enable, back as the message (process id 0).
pub fn decode_enable(data: &[u8]) -> Result<OperatorEnableMsg, DecodeError> {
    let j: EnableJson = parse(Channel::OperatorEnable, data)?;
    Ok(OperatorEnableMsg {
        seq: j.seq,
        stamp_ns: j.stamp_ns,
        pid: 0,
        reserved: 0,
    })
}

#[derive(Serialize, Deserialize)]
struct CanJson {
    id: u32,
    extended: bool,
    data: Vec<u8>,
}

/// A CAN frame.
pub fn encode_can(f: &CanFrame) -> Vec<u8> {
    let id = f.id();
    to_vec(&CanJson {
        id: id.raw(),
        extended: id.is_extended(),
        data: f.data().to_vec(),
    })
}

/// A logged CAN frame, back as the frame (id and length checked).
pub fn decode_can(data: &[u8]) -> Result<CanFrame, DecodeError> {
    let j: CanJson = parse(Channel::Can, data)?;
    let content = |detail: String| DecodeError::Content {
        channel: Channel::Can.topic(),
        detail,
    };
    let id = if j.extended {
        CanId::extended(j.id).map_err(|e| content(e.to_string()))?
    } else {
        let raw = u16::try_from(j.id)
            .map_err(|_| content(format!("standard CAN id 0x{:X} is out of range", j.id)))?;
        CanId::standard(raw).map_err(|e| content(e.to_string()))?
    };
    CanFrame::new(id, &j.data).map_err(|e| content(e.to_string()))
}

#[cfg(test)]
#[path = "codec_tests.rs"]
mod tests;
