//! `grop replay`: re-runs the planning node and the executive of a logged mission against the
//! log's recorded inputs, in simulated time, and reports the first message where what they do
//! now differs from what they did then (none for an unchanged build).
//!
//! What stands in for the world: the camera frames, localisation fixes, the world's heartbeats
//! and events are published again at the instants they were logged; the base's CAN frames come
//! from a tape of the logged bus (the executive's own frames are taken from it, compared, not
//! replayed); the arm answers every call with the answer it gave then (`arm/io`). Everything the
//! two nodes publish, send and call is recorded by the same recorder code into a second log,
//! which is compared with the first message by message (channel, simulated time, payload;
//! wall-clock measurements under `/timing/` excepted). Same instants, same inputs, same order:
//! an unchanged build logs the same messages.

use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use can_bus::{CanBus, CanFrame, RecvError, SendError};
use grop_clock::{Clock, HostConfig, SimClock, SimClockHost};
use grop_ipc::{ArmCall, ArmIoMsg, IpcNode, ProcessRole};
use ur5e_kin::Joints;

use super::codec::{self, Channel};
use super::reader::{LoggedMessage, MissionLog};
use super::writer::{LogWriter, Overflow, WriterConfig};
use super::{LogError, MISSION_METADATA, RECORDER_METADATA, Recorder, RecorderConfig};
use crate::deployment::Deployment;
use crate::executive::arm_io::{self, RecordingArm};
use crate::executive::unload::{ArmFault, ArmPort, SkillStatus};
use crate::executive::{ArmDevice, ArmSnapshot, Executive, ExecutiveConfig};
use crate::planner_node::{PLANNER_CLOCK_RANK, PlannerNode};

/// CAN ids the host (the executive's driver) sends: RMP v3 motion, configuration, omni motion.
const HOST_IDS: [u32; 3] = [0x500, 0x501, 0x600];

/// Ranks as in the live processes.
const EXECUTIVE_RANK: u32 = 20;
const RECORDER_RANK: u32 = 90;
/// The world's step (the live world steps every 2 ms).
const STEP: Duration = Duration::from_millis(2);
/// When a replay of a log from before the operator enable (format 1 and 2) gives it.
const STAND_IN_ENABLE_AT: Duration = Duration::from_millis(10);
/// Stages of feeding a recorded input.
const DECODE: &str = "decoding a logged input";
const PUBLISH: &str = "publishing a logged input";

/// Why a replay could not run. (A difference is not an error: it is in [`ReplayReport`].)
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReplayError {
    /// Reading the log or writing the replay's log.
    #[error(transparent)]
    Log(#[from] LogError),
    /// The log lacks what a replay needs.
    #[error("{0}")]
    NotReplayable(String),
    /// The model file is not the one the mission ran with.
    #[error(
        "the model {} has changed since the mission (SHA-256 {actual}, the log says {expected}): pass --model with the mission's model",
        path.display()
    )]
    ModelChanged {
        /// The model file.
        path: PathBuf,
        /// Its SHA-256 now.
        actual: String,
        /// The SHA-256 the log names.
        expected: String,
    },
    /// A step of setting up or running the replay failed; `stage` says which.
    #[error("{stage}")]
    Stage {
        /// What was being done.
        stage: String,
        /// Why it failed.
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// The replayed nodes did not all join the simulated clock.
    #[error("the replayed nodes did not start within a minute")]
    NotStarted,
    /// A replayed node's thread panicked.
    #[error("the replayed {0} panicked")]
    Panicked(&'static str),
}

impl ReplayError {
    /// `error` while doing `stage`.
    fn stage(
        stage: impl Into<String>,
        error: impl Into<Box<dyn std::error::Error + Send + Sync + 'static>>,
    ) -> Self {
        Self::Stage {
            stage: stage.into(),
            source: error.into(),
        }
    }
}

/// `.map_err(at("doing x"))`: an error while doing x.
fn at<E: Into<Box<dyn std::error::Error + Send + Sync + 'static>>>(
    stage: &'static str,
) -> impl FnOnce(E) -> ReplayError {
    move |e| ReplayError::stage(stage, e)
}

/// What a replay found.
#[derive(Debug, Clone)]
pub struct ReplayReport {
    /// The log the replay wrote (same format as the recorded one).
    pub replay_log: PathBuf,
    /// Messages compared (recorded, `/timing/` excepted).
    pub recorded: usize,
    /// Messages the replay logged (`/timing/` excepted).
    pub replayed: usize,
    /// Simulated seconds replayed.
    pub sim_s: f64,
    /// The first difference, if any.
    pub first_difference: Option<Difference>,
    /// Arm calls the replay asked for that the log did not have in that order.
    pub arm_mismatches: u64,
}

/// The first message where the replay differs from the log.
#[derive(Debug, Clone)]
pub struct Difference {
    /// Position among the compared messages.
    pub index: usize,
    /// Recorded message there (channel, simulated time, payload), if the log has one.
    pub recorded: Option<(Channel, u64, String)>,
    /// Replayed message there, if the replay has one.
    pub replayed: Option<(Channel, u64, String)>,
}

impl std::fmt::Display for Difference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let show = |m: &Option<(Channel, u64, String)>| match m {
            Some((c, t, data)) => format!(
                "{} at {:.3} s: {}",
                c.topic(),
                *t as f64 * 1e-9,
                data.chars().take(400).collect::<String>()
            ),
            None => "(nothing: the log ends here)".to_owned(),
        };
        write!(
            f,
            "message {}:\n  recorded {}\n  replayed {}",
            self.index,
            show(&self.recorded),
            show(&self.replayed)
        )
    }
}

/// Settings of a replay.
#[derive(Debug, Clone, Default)]
pub struct ReplayOptions {
    /// Use this model instead of the one the log names.
    pub model: Option<PathBuf>,
    /// Where to write the replay's log (default: next to the recorded one, `.replay.mcap`).
    pub out: Option<PathBuf>,
}

/// Whether a logged message is something the two nodes made (compared) rather than an input.
/// Whether a replay compares this message: behaviour only. Not the wall-clock measurements
/// under `/timing/`, not the views in Foxglove's schemas (`Channel::is_view`), which the
/// recorder derives from the compared messages (and which logs before `log_format` 4 lack), and
/// not the range sensor's revolutions (`/scan`): the sensor's packets are not in the log, so the
/// replayed executive runs without it; and not the simulated world's truth (`/world/truth`),
/// which no onboard process reads and a replay has no world to make.
pub fn compared(m: &LoggedMessage) -> bool {
    !m.channel.topic().starts_with("/timing/")
        && !m.channel.is_view()
        && !matches!(m.channel, Channel::Scan | Channel::Truth)
}

fn is_world_input(m: &LoggedMessage) -> bool {
    match m.channel {
        Channel::CameraFrame | Channel::BasePose | Channel::OperatorEnable => true,
        Channel::Health => codec::decode_health(&m.data)
            .is_ok_and(|h| h.role().is_ok_and(|r| r == ProcessRole::World)),
        Channel::Events => {
            codec::decode_event(&m.data).is_ok_and(|e| e.source() == Some(ProcessRole::World))
        }
        _ => false,
    }
}

/// Frames the base sent, with the time they were logged.
type Tape = Arc<Vec<(u64, CanFrame)>>;

fn now_ns(clock: &dyn Clock) -> u64 {
    u64::try_from(clock.now().as_nanos()).unwrap_or(u64::MAX)
}

/// The executive's bus: the base's logged frames at their times; what it sends goes to the
/// recorder's tap.
struct ReplayBus {
    tape: Tape,
    next: usize,
    clock: Arc<dyn Clock>,
    sent: Arc<Mutex<VecDeque<CanFrame>>>,
}

impl CanBus for ReplayBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        if let Ok(mut q) = self.sent.lock() {
            q.push_back(*frame);
        }
        Ok(())
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        let now = now_ns(self.clock.as_ref());
        match self.tape.get(self.next) {
            Some((t, f)) if *t <= now => {
                self.next += 1;
                Ok(Some(*f))
            }
            _ => Ok(None),
        }
    }

    fn recv_timeout(&mut self, _timeout: Duration) -> Result<Option<CanFrame>, RecvError> {
        self.try_recv()
    }
}

/// The recorder's view of the bus: the base's frames of this instant, then the executive's (the
/// order the live bus has: the world's step precedes the executive's next cycle).
struct Tap {
    tape: Tape,
    next: usize,
    clock: Arc<dyn Clock>,
    sent: Arc<Mutex<VecDeque<CanFrame>>>,
}

impl CanBus for Tap {
    fn send(&mut self, _frame: &CanFrame) -> Result<(), SendError> {
        Ok(())
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        let now = now_ns(self.clock.as_ref());
        if let Some((t, f)) = self.tape.get(self.next) {
            if *t <= now {
                self.next += 1;
                return Ok(Some(*f));
            }
        }
        Ok(self.sent.lock().ok().and_then(|mut q| q.pop_front()))
    }

    fn recv_timeout(&mut self, _timeout: Duration) -> Result<Option<CanFrame>, RecvError> {
        self.try_recv()
    }
}

/// The arm, answering from the log.
struct ReplayArm {
    calls: Vec<ArmIoMsg>,
    next: usize,
    mismatches: Arc<std::sync::atomic::AtomicU64>,
}

impl ReplayArm {
    /// The next logged call, if it is a `call`.
    fn take(&mut self, call: ArmCall) -> Option<ArmIoMsg> {
        let m = *self.calls.get(self.next)?;
        self.next += 1;
        if m.call().ok() == Some(call) {
            Some(m)
        } else {
            self.mismatches.fetch_add(1, Ordering::Relaxed);
            None
        }
    }

    fn outcome(&mut self, call: ArmCall) -> Result<ArmIoMsg, ArmFault> {
        let m = self.take(call).ok_or(ArmFault::LinkLost)?;
        arm_io::fault_of(m.outcome().map_err(|_| ArmFault::LinkLost)?)?;
        Ok(m)
    }
}

impl ArmPort for ReplayArm {
    fn start_move_joints(&mut self, _q: &Joints, _now: Duration) -> Result<(), ArmFault> {
        self.outcome(ArmCall::StartMoveJoints).map(|_| ())
    }

    fn start_gripper(&mut self, _close: bool, _now: Duration) -> Result<(), ArmFault> {
        self.outcome(ArmCall::StartGripper).map(|_| ())
    }

    fn poll(&mut self, _now: Duration) -> Result<SkillStatus, ArmFault> {
        self.outcome(ArmCall::Poll)
            .map(|m| arm_io::status_of(m.status))
    }
}

impl ArmDevice for ReplayArm {
    fn update(&mut self, _now: Duration) -> Result<ArmSnapshot, ArmFault> {
        self.outcome(ArmCall::Update)
            .map(|m| arm_io::snapshot_of(&m))
    }

    fn stop(&mut self, _now: Duration) {
        let _ = self.take(ArmCall::Stop);
    }
}

/// The deployment the log was recorded with, its files written into `dir`, on a fresh
/// namespace and simulated clock.
fn deployment_of(
    log: &MissionLog,
    dir: &Path,
    run: &str,
    model: Option<&Path>,
) -> Result<Deployment, ReplayError> {
    let meta = log.metadata.get(MISSION_METADATA).ok_or_else(|| {
        ReplayError::NotReplayable(format!(
            "no `{MISSION_METADATA}` metadata: not a log written by grop-recorder"
        ))
    })?;
    let field = |k: &str| {
        meta.get(k).ok_or_else(|| {
            ReplayError::NotReplayable(format!(
                "the log's `{MISSION_METADATA}` metadata has no `{k}`"
            ))
        })
    };
    let write = |path: &Path, text: &str| {
        std::fs::write(path, text)
            .map_err(|e| ReplayError::stage(format!("writing {}", path.display()), e))
    };
    let file_name = |k: &str, default: &str| {
        meta.get(k)
            .and_then(|p| Path::new(p).file_name().map(|n| n.to_owned()))
            .unwrap_or_else(|| default.into())
    };
    std::fs::create_dir_all(dir)
        .map_err(|e| ReplayError::stage(format!("creating {}", dir.display()), e))?;
    let deployment_path = dir.join("deployment.toml");
    let text = field("deployment")?;
    write(&deployment_path, text)?;
    let map = dir.join(file_name("map_file", "map.toml"));
    write(&map, field("map")?)?;
    let mut d = Deployment::from_toml_str(text, &deployment_path)
        .map_err(at("the log's deployment file"))?;
    d.map = map;
    d.robot = match meta.get("robot") {
        Some(robot) => {
            let path = dir.join(file_name("robot_file", "robot.toml"));
            write(&path, robot)?;
            Some(path)
        }
        None => None,
    };
    d.model = match model {
        Some(m) => m.to_owned(),
        None => PathBuf::from(field("model_path")?),
    };
    if let Some(expected) = meta.get("model_sha256").filter(|_| model.is_none()) {
        use sha2::Digest;
        let bytes = std::fs::read(&d.model)
            .map_err(|e| ReplayError::stage(format!("the log's model {}", d.model.display()), e))?;
        let actual: String = sha2::Sha256::digest(&bytes)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        if &actual != expected {
            return Err(ReplayError::ModelChanged {
                path: d.model.clone(),
                actual,
                expected: expected.clone(),
            });
        }
    }
    d.namespace = run.to_owned();
    d.clock = format!("sim:{run}");
    d.validate().map_err(at("the log's deployment"))?;
    Ok(d)
}

/// Replays the log at `path` (see the module docs).
pub fn replay(path: &Path, options: &ReplayOptions) -> Result<ReplayReport, ReplayError> {
    let log = MissionLog::read(path)?;
    let run = format!(
        "replay-{}-{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.subsec_nanos() & 0xffff)
            .unwrap_or(0)
    );
    let dir = std::env::temp_dir().join(format!("grop-{run}"));
    let result = replay_in(&log, path, options, &run, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

#[allow(
    clippy::too_many_lines,
    reason = "a replay in order: the log, the ports, the loop, the digest"
)]
fn replay_in(
    log: &MissionLog,
    path: &Path,
    options: &ReplayOptions,
    run: &str,
    dir: &Path,
) -> Result<ReplayReport, ReplayError> {
    let deployment = deployment_of(log, dir, run, options.model.as_deref())?;
    let scene = deployment.load_scene().map_err(at("the log's map"))?;
    let robot = deployment
        .load_robot()
        .map_err(at("the log's robot file"))?;
    let camera_period_s: f64 = log
        .metadata
        .get(RECORDER_METADATA)
        .and_then(|m| m.get("camera_period_s"))
        .and_then(|v| v.parse().ok())
        .unwrap_or(1.0);
    let out = options
        .out
        .clone()
        .unwrap_or_else(|| path.with_extension("replay.mcap"));

    // The recorded inputs.
    let mut tape: Vec<(u64, CanFrame)> = Vec::new();
    // Whether the recorded driver wrote stored settings into the base (it writes the robot's
    // limits where the base holds others; before issue 25 it never did).
    let mut wrote_settings = false;
    let mut arm_calls: Vec<ArmIoMsg> = Vec::new();
    let mut inputs: Vec<&LoggedMessage> = Vec::new();
    for m in &log.messages {
        match m.channel {
            Channel::Can => {
                let f = codec::decode_can(&m.data).map_err(at("a logged CAN frame"))?;
                if !HOST_IDS.contains(&f.id().raw()) {
                    tape.push((m.log_time, f));
                } else if rmp_base::from_can(&f).is_some_and(|raw| {
                    matches!(
                        rmp_codec::v3::ConfigCommand::decode(
                            rmp_codec::v3::FirmwareProfile::SegwayInc2014,
                            &raw
                        ),
                        Ok(rmp_codec::v3::ConfigCommand::SetFloat(..))
                    )
                }) {
                    wrote_settings = true;
                }
            }
            Channel::ArmIo => {
                arm_calls.push(codec::decode_arm_io(&m.data).map_err(at("a logged arm call"))?)
            }
            _ if is_world_input(m) => inputs.push(m),
            _ => {}
        }
    }
    // Frames a plan named may have been logged later than they were seen: feed by time.
    inputs.sort_by_key(|m| m.log_time);
    let end_ns = log.messages.iter().map(|m| m.log_time).max().unwrap_or(0);
    let tape: Tape = Arc::new(tape);

    let mut host = SimClockHost::create(&deployment.clock[4..], HostConfig::default())
        .map_err(at("creating the replay's clock"))?;
    let clock_name = deployment.clock[4..].to_owned();
    let stop = AtomicBool::new(false);
    let mismatches = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let mut metadata = BTreeMap::new();
    if let Some(m) = log.metadata.get(MISSION_METADATA) {
        metadata.insert(MISSION_METADATA.to_owned(), m.clone());
    }
    let writer = LogWriter::create(
        &out,
        metadata,
        WriterConfig {
            overflow: Overflow::Block,
            ..WriterConfig::default()
        },
    )?;
    let feeder = IpcNode::new(&deployment.namespace, "replay-world").map_err(at("iceoryx2"))?;
    let publishers = "the replay's publishers";
    let frames = feeder
        .publisher::<grop_ipc::CameraFrameMsg>()
        .map_err(at(publishers))?;
    let poses = feeder
        .publisher::<grop_ipc::BasePoseMsg>()
        .map_err(at(publishers))?;
    let health = feeder
        .publisher::<grop_ipc::HeartbeatMsg>()
        .map_err(at(publishers))?;
    let events = feeder
        .publisher::<grop_ipc::EventMsg>()
        .map_err(at(publishers))?;
    let enables = feeder
        .publisher::<grop_ipc::OperatorEnableMsg>()
        .map_err(at(publishers))?;
    // Logs before format 3 have no operator: their executive armed at start. Stand in for the
    // operator once the executive runs (it takes only an enable given after its start).
    let mut stand_in_enable = log.log_format < 3;

    let join = |name: &str, rank: u32| -> Result<Arc<dyn Clock>, ReplayError> {
        Ok(Arc::new(
            SimClock::join(&clock_name, name, rank, Duration::from_secs(10))
                .map_err(|e| ReplayError::stage(format!("{name} joining the replay's clock"), e))?,
        ))
    };
    let participants = 3;
    // The executive's outgoing CAN frames, for the recorder's tap.
    let sent: Arc<Mutex<VecDeque<CanFrame>>> = Arc::new(Mutex::new(VecDeque::new()));
    std::thread::scope(|s| -> Result<ReplayReport, ReplayError> {
        let planner = s.spawn(|| -> Result<(), ReplayError> {
            let mut node = PlannerNode::from_deployment(&deployment).map_err(at("the planner"))?;
            let clock = join("replay-planner", PLANNER_CLOCK_RANK)?;
            node.run(clock.as_ref(), &stop).map_err(at("the planner"))?;
            Ok(())
        });
        let executive = s.spawn(|| -> Result<(), ReplayError> {
            let clock = join("replay-executive", EXECUTIVE_RANK)?;
            let node =
                IpcNode::new(&deployment.namespace, "replay-executive").map_err(at("iceoryx2"))?;
            let bus = ReplayBus {
                tape: Arc::clone(&tape),
                next: 0,
                clock: Arc::clone(&clock),
                sent: Arc::clone(&sent),
            };
            let arm = ReplayArm {
                calls: arm_calls,
                next: 0,
                mismatches: Arc::clone(&mismatches),
            };
            let arm = RecordingArm::new(arm, &node).map_err(at("the arm's log port"))?;
            // The recorded fixes come from the replay's feeder.
            let mut config = ExecutiveConfig::for_robot(&robot);
            config.inputs.fixes = "replay-world".into();
            config.inputs.operator = "replay-world".into();
            // A recorded driver that wrote no limits took the base's as they were (a log from
            // before issue 25, or a base configured by an earlier start): replay it so.
            config.adopt_base_limits = !wrote_settings;
            let mut exec = Executive::new(
                config,
                Arc::clone(&clock),
                bus,
                arm,
                &node,
                scene.clone(),
                scene.targets.len(),
            )
            .map_err(at("the executive"))?;
            exec.run(&|| !stop.load(Ordering::Relaxed), false);
            Ok(())
        });
        let recorder = s.spawn(|| -> Result<(), ReplayError> {
            let clock = join("replay-recorder", RECORDER_RANK)?;
            let node =
                IpcNode::new(&deployment.namespace, "replay-recorder").map_err(at("iceoryx2"))?;
            let tap = Tap {
                tape: Arc::clone(&tape),
                next: 0,
                clock: Arc::clone(&clock),
                sent: Arc::clone(&sent),
            };
            let mut rec = Recorder::new(
                &node,
                Some(Box::new(tap)),
                writer,
                RecorderConfig {
                    camera_period_ns: (camera_period_s * 1e9) as u64,
                },
            )?
            .with_views(super::Views::new(scene.clone(), &robot));
            clock.wait_turn();
            let mut deadline = clock.now();
            while !clock.is_lost() {
                rec.drain(now_ns(clock.as_ref()));
                deadline += STEP;
                clock.sleep_until(deadline);
            }
            rec.finish(None)?;
            Ok(())
        });

        // Wait for the three, then play the world.
        let started = std::time::Instant::now();
        while host.participants().len() < participants {
            if started.elapsed() > Duration::from_secs(60) {
                stop.store(true, Ordering::Relaxed);
                return Err(ReplayError::NotStarted);
            }
            if planner.is_finished() || executive.is_finished() || recorder.is_finished() {
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        host.settle();
        let mut next_input = 0;
        let mut t = Duration::ZERO;
        let mut feed_error: Option<ReplayError> = None;
        loop {
            let now = u64::try_from(t.as_nanos()).unwrap_or(u64::MAX);
            while let Some(m) = inputs.get(next_input).filter(|m| m.log_time <= now) {
                next_input += 1;
                let published = match m.channel {
                    Channel::CameraFrame => {
                        let mut result = Ok(());
                        let p = frames.publish_with(|f| {
                            result = codec::decode_camera_into(&m.data, f);
                        });
                        result
                            .map_err(at(DECODE))
                            .and(p.map(|_| ()).map_err(at(PUBLISH)))
                    }
                    Channel::BasePose => codec::decode_base_pose(&m.data)
                        .map_err(at(DECODE))
                        .and_then(|f| poses.publish(&f).map(|_| ()).map_err(at(PUBLISH))),
                    Channel::Health => codec::decode_health(&m.data)
                        .map_err(at(DECODE))
                        .and_then(|h| health.publish(&h).map(|_| ()).map_err(at(PUBLISH))),
                    Channel::Events => codec::decode_event(&m.data)
                        .map_err(at(DECODE))
                        .and_then(|e| events.publish(&e).map(|_| ()).map_err(at(PUBLISH))),
                    Channel::OperatorEnable => codec::decode_enable(&m.data)
                        .map_err(at(DECODE))
                        .and_then(|mut e| {
                            // The replay's feeder is the operator now (the executive checks
                            // that an enable names its sender's process).
                            e.pid = std::process::id();
                            enables.publish(&e).map(|_| ()).map_err(at(PUBLISH))
                        }),
                    _ => Ok(()),
                };
                if let Err(e) = published {
                    feed_error.get_or_insert(e);
                }
            }
            if stand_in_enable && t >= STAND_IN_ENABLE_AT {
                stand_in_enable = false;
                let enable = grop_ipc::OperatorEnableMsg {
                    seq: 1,
                    stamp_ns: now,
                    pid: std::process::id(),
                    reserved: 0,
                };
                if let Err(e) = enables.publish(&enable) {
                    feed_error.get_or_insert(at(PUBLISH)(e));
                }
            }
            host.advance_to(t);
            if now >= end_ns || feed_error.is_some() {
                break;
            }
            if planner.is_finished() || executive.is_finished() || recorder.is_finished() {
                break;
            }
            t += STEP;
        }
        stop.store(true, Ordering::Relaxed);
        drop(host);
        let results = [
            ("planner", planner.join()),
            ("executive", executive.join()),
            ("recorder", recorder.join()),
        ];
        for (name, r) in results {
            match r {
                Ok(Ok(())) => {}
                Ok(Err(e)) => return Err(ReplayError::stage(format!("the replayed {name}"), e)),
                Err(_) => return Err(ReplayError::Panicked(name)),
            }
        }
        if let Some(e) = feed_error {
            return Err(ReplayError::stage("feeding the recorded inputs", e));
        }
        let replayed = MissionLog::read(&out)?;
        let a: Vec<&LoggedMessage> = log.messages.iter().filter(|m| compared(m)).collect();
        let b: Vec<&LoggedMessage> = replayed.messages.iter().filter(|m| compared(m)).collect();
        let show = |m: Option<&&LoggedMessage>| {
            m.map(|m| {
                (
                    m.channel,
                    m.log_time,
                    String::from_utf8_lossy(&m.data).into_owned(),
                )
            })
        };
        let first_difference = (0..a.len().max(b.len()))
            .find(|&i| match (a.get(i), b.get(i)) {
                (Some(x), Some(y)) => {
                    x.channel != y.channel || x.log_time != y.log_time || x.data != y.data
                }
                _ => true,
            })
            .map(|i| Difference {
                index: i,
                recorded: show(a.get(i)),
                replayed: show(b.get(i)),
            });
        Ok(ReplayReport {
            replay_log: out.clone(),
            recorded: a.len(),
            replayed: b.len(),
            sim_s: t.as_secs_f64(),
            first_difference,
            arm_mismatches: mismatches.load(Ordering::Relaxed),
        })
    })
}
