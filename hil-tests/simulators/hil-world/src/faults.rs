//! Fault injection over the closed loop (docs/reliability.md).
//!
//! The world injects one fault per mission, named on its command line (`--fault
//! KIND[@TRIGGER]`), where the onboard processes cannot tell it from the real thing: on the
//! CAN bus between the base and everyone else ([`FaultyBus`] wraps the simulated base's bus
//! node: frames lost, duplicated, delayed, reordered, corrupted; a second host commanding the
//! base), at the simulated UR5e's sockets (RTDE cut or silent while connected, gripper
//! unanswered, dashboard replies late), in the devices themselves (base fault word, kill
//! switch, protective and emergency stop, gripper fault), in what the world publishes (corrupt
//! camera frames, a localisation jump) and in time itself (a clock jump). The drivers and the
//! onboard processes are the unchanged binaries.
//!
//! The world records when the fault began and what followed ([`FaultRecord`]): when the
//! executive's commands reached zero, when the base and the arm stood still, and the largest
//! command the base received over the whole mission (to hold against the robot file's
//! limits).

use std::collections::VecDeque;
use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use can_bus::{CanBus, CanFrame, CanId, RecvError, SendError};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rmp_codec::RawFrame;
use rmp_codec::v3::{MOTION_ID, MotionCommand};
use serde::{Deserialize, Serialize};

/// Every fault the world can inject.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FaultKind {
    /// Every CAN frame, both ways, lost for 0.4 s (longer than the driver's 250 ms).
    CanLossBurst,
    /// 5 % of CAN frames lost at random, both ways, for the rest of the mission.
    CanLossRandom,
    /// Every CAN frame delivered twice.
    CanDuplicate,
    /// Every CAN frame delayed 5-15 ms (uniform jitter: frames of one feedback set arrive
    /// shuffled), both ways.
    CanDelay,
    /// Pairs of consecutive CAN frames swapped, both ways.
    CanReorder,
    /// The base's feedback frames corrupted (every data byte XOR a random byte).
    CanCorruptFeedback,
    /// The bus goes silent: nothing gets through either way, for good.
    CanSilent,
    /// The base reports a fault that stops motion (velocity control failed).
    BaseFaultWord,
    /// The base's kill switch, released 1 s later (then the operator enables).
    KillSwitch,
    /// Another host sends motion commands on the bus for 0.2 s.
    SecondCommander,
    /// Every RTDE connection cut while the arm moves.
    RtdeDrop,
    /// The controller stays connected but stops sending RTDE data.
    RtdeSilent,
    /// A protective stop while the arm moves, unlocked 1 s later (then the operator enables).
    ProtectiveStop,
    /// An emergency stop while the arm moves, released 1 s later (then the operator enables).
    EmergencyStop,
    /// The arm's safeguard input opens for 2 s while the base drives (a person near the
    /// robot: UR safety mode 5), then closes again; the operator enables 1 s later.
    SafeguardStop,
    /// The gripper reports a fault.
    GripperFault,
    /// The gripper stops answering (connection open).
    GripperTimeout,
    /// Dashboard replies arrive 3 s late (longer than the client's 2 s deadline), and the
    /// RTDE link is cut while the arm moves: the driver's stop then goes out by URScript and
    /// by the dashboard (whose reply never comes in time).
    DashboardLate,
    /// Camera frames with a corrupt header (row stride shorter than a row) for 3 s.
    CameraCorrupt,
    /// Simulated time jumps 1 s at once (a stalled machine).
    ClockJump,
    /// One global localisation fix 1.5 m off the truth.
    LocalisationJump,
    /// The overhead camera sees only the west quarter of its frame from then on (its header
    /// says so: a camera that no longer covers the room); the planner must treat the rest of
    /// the room as unknown.
    CameraNarrow,
}

impl FaultKind {
    /// Every kind, in the order of docs/reliability.md.
    pub const ALL: [FaultKind; 22] = [
        FaultKind::CanLossBurst,
        FaultKind::CanLossRandom,
        FaultKind::CanDuplicate,
        FaultKind::CanDelay,
        FaultKind::CanReorder,
        FaultKind::CanCorruptFeedback,
        FaultKind::CanSilent,
        FaultKind::BaseFaultWord,
        FaultKind::KillSwitch,
        FaultKind::SecondCommander,
        FaultKind::RtdeDrop,
        FaultKind::RtdeSilent,
        FaultKind::ProtectiveStop,
        FaultKind::EmergencyStop,
        FaultKind::GripperFault,
        FaultKind::GripperTimeout,
        FaultKind::DashboardLate,
        FaultKind::CameraCorrupt,
        FaultKind::ClockJump,
        FaultKind::LocalisationJump,
        FaultKind::CameraNarrow,
        FaultKind::SafeguardStop,
    ];

    /// The command-line name (`can-loss-burst`).
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::CanLossBurst => "can-loss-burst",
            FaultKind::CanLossRandom => "can-loss-random",
            FaultKind::CanDuplicate => "can-duplicate",
            FaultKind::CanDelay => "can-delay",
            FaultKind::CanReorder => "can-reorder",
            FaultKind::CanCorruptFeedback => "can-corrupt-feedback",
            FaultKind::CanSilent => "can-silent",
            FaultKind::BaseFaultWord => "base-fault-word",
            FaultKind::KillSwitch => "kill-switch",
            FaultKind::SecondCommander => "second-commander",
            FaultKind::RtdeDrop => "rtde-drop",
            FaultKind::RtdeSilent => "rtde-silent",
            FaultKind::ProtectiveStop => "protective-stop",
            FaultKind::EmergencyStop => "emergency-stop",
            FaultKind::GripperFault => "gripper-fault",
            FaultKind::GripperTimeout => "gripper-timeout",
            FaultKind::DashboardLate => "dashboard-late",
            FaultKind::CameraCorrupt => "camera-corrupt",
            FaultKind::ClockJump => "clock-jump",
            FaultKind::LocalisationJump => "localisation-jump",
            FaultKind::CameraNarrow => "camera-narrow",
            FaultKind::SafeguardStop => "safeguard-stop",
        }
    }

    /// How long after it struck the fault is released, for the kinds a person releases.
    pub fn released_after(self) -> Option<Duration> {
        match self {
            FaultKind::KillSwitch | FaultKind::ProtectiveStop | FaultKind::EmergencyStop => {
                Some(Duration::from_secs(1))
            }
            _ => None,
        }
    }

    /// When it strikes unless the command line says otherwise.
    pub fn default_trigger(self) -> Trigger {
        match self {
            FaultKind::RtdeDrop
            | FaultKind::RtdeSilent
            | FaultKind::ProtectiveStop
            | FaultKind::EmergencyStop
            | FaultKind::GripperTimeout
            | FaultKind::DashboardLate => Trigger::ArmMoving,
            // Injected while the gripper is idle, the fault is cleared by the unload's
            // activation (as a Robotiq's is): strike while it works.
            FaultKind::GripperFault => Trigger::Gripping,
            FaultKind::CameraCorrupt | FaultKind::CameraNarrow => Trigger::At(Duration::ZERO),
            _ => Trigger::Driving,
        }
    }
}

impl fmt::Display for FaultKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// When the fault strikes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Trigger {
    /// The first time the base drives faster than 0.3 m/s.
    Driving,
    /// The first time a joint moves faster than 0.3 rad/s.
    ArmMoving,
    /// The first time a joint moves faster than 0.3 rad/s while the gripper is activated (the
    /// arm at work on an object: a gripper fault before activation is cleared by it).
    Gripping,
    /// This long after the mission started (simulated).
    At(Duration),
}

/// One fault of one mission: `KIND` or `KIND@driving`, `KIND@arm`, `KIND@gripping`, `KIND@SECONDS`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FaultSpec {
    /// What.
    pub kind: FaultKind,
    /// When.
    pub trigger: Trigger,
}

/// A fault the command line cannot name.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FaultParseError {
    /// Unknown kind.
    #[error("unknown fault {0:?}; the kinds are: {list}", list = FaultKind::ALL.map(FaultKind::name).join(", "))]
    Kind(String),
    /// Unknown trigger.
    #[error("fault trigger {0:?}: expected driving, arm or a time in seconds")]
    Trigger(String),
}

impl FromStr for FaultSpec {
    type Err = FaultParseError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (kind, trigger) = match s.split_once('@') {
            Some((k, t)) => (k, Some(t)),
            None => (s, None),
        };
        let kind = FaultKind::ALL
            .into_iter()
            .find(|k| k.name() == kind.trim())
            .ok_or_else(|| FaultParseError::Kind(kind.to_owned()))?;
        let trigger = match trigger.map(str::trim) {
            None => kind.default_trigger(),
            Some("driving") => Trigger::Driving,
            Some("arm") => Trigger::ArmMoving,
            Some("gripping") => Trigger::Gripping,
            Some(t) => match t.parse::<f64>() {
                Ok(s) if s.is_finite() && (0.0..1e6).contains(&s) => {
                    Trigger::At(Duration::from_secs_f64(s))
                }
                _ => return Err(FaultParseError::Trigger(t.to_owned())),
            },
        };
        Ok(Self { kind, trigger })
    }
}

impl fmt::Display for FaultSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.trigger {
            Trigger::Driving => write!(f, "{}@driving", self.kind),
            Trigger::ArmMoving => write!(f, "{}@arm", self.kind),
            Trigger::Gripping => write!(f, "{}@gripping", self.kind),
            Trigger::At(t) => write!(f, "{}@{}", self.kind, t.as_secs_f64()),
        }
    }
}

/// What the world saw of a fault (part of the report).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FaultRecord {
    /// The fault as given.
    pub spec: String,
    /// When it struck (simulated s); `None`: its trigger never came.
    pub injected_at_s: Option<f64>,
    /// Base speed then (m/s, truth).
    pub base_speed_then_mps: f64,
    /// Fastest joint then (rad/s).
    pub arm_speed_then_radps: f64,
    /// First instant at or after the fault from which every motion command the executive sent
    /// was zero (s); `None`: it never stopped commanding motion, or sent nothing after.
    pub commanded_zero_at_s: Option<f64>,
    /// First zero motion command the executive sent at or after the fault.
    #[serde(default)]
    pub first_zero_command_at_s: Option<f64>,
    /// First instant after the fault at which the base stood still (truth).
    pub base_stopped_at_s: Option<f64>,
    /// First instant after the fault at which the arm stood still.
    pub arm_stopped_at_s: Option<f64>,
    /// CAN frames the injector dropped, duplicated, delayed, reordered, corrupted, sent as a
    /// second commander.
    pub can: CanFaultCounts,
    /// First instant at or after the fault at which the simulated controller received a
    /// program with a `stopj` (the onboard stop; the controller's own stops are not counted).
    #[serde(default)]
    pub arm_stop_asked_at_s: Option<f64>,
    /// Dashboard `stop` commands the controller received after the fault.
    #[serde(default)]
    pub dashboard_stops: u64,
    /// When the fault was released (an e-stop pulled out, the kill switch reset, a protective
    /// stop unlocked), for the kinds that are.
    #[serde(default)]
    pub released_at_s: Option<f64>,
    /// When the operator's enable was given after the release.
    #[serde(default)]
    pub enabled_after_release_at_s: Option<f64>,
    /// Farthest the base moved from where it stood at the release, m (truth).
    #[serde(default)]
    pub base_moved_after_release_m: f64,
    /// Farthest a joint moved from where it stood at the release, rad.
    #[serde(default)]
    pub arm_moved_after_release_rad: f64,
}

/// What the CAN injector did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CanFaultCounts {
    /// Frames lost.
    pub dropped: u64,
    /// Frames sent twice.
    pub duplicated: u64,
    /// Frames held back.
    pub delayed: u64,
    /// Frames swapped with the next.
    pub reordered: u64,
    /// Frames corrupted.
    pub corrupted: u64,
    /// Frames sent by the second commander.
    pub intruder: u64,
}

/// The motion commands the base received over a mission (before any fault touched them).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct CommandMonitor {
    /// 0x500 frames seen.
    pub frames: u64,
    /// 0x500 frames outside [-1, 1] or not finite (the firmware would reject them).
    pub malformed: u64,
    /// Largest |speed| commanded (normalised command x the base's velocity limit), m/s.
    pub max_speed_mps: f64,
    /// Largest |yaw rate| commanded, rad/s.
    pub max_yaw_rate_radps: f64,
    /// The last command, m/s and rad/s.
    pub last: (f64, f64),
    /// Since when every command has been zero (simulated s).
    pub zero_since_s: Option<f64>,
    /// The first zero command at or after [`FaultyBus::mark`].
    pub first_zero_after_mark_s: Option<f64>,
    /// The mark.
    pub mark_s: Option<f64>,
}

/// The CAN fault in effect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CanFault {
    /// Frames pass.
    None,
    /// Each frame lost with probability `p` (1 = nothing passes).
    Loss {
        /// Loss probability.
        p: f64,
    },
    /// Each frame twice.
    Duplicate,
    /// Each frame held back by a uniform delay in `[min, max]`.
    Delay {
        /// Shortest delay.
        min: Duration,
        /// Longest delay.
        max: Duration,
    },
    /// Consecutive frames swapped.
    Reorder,
    /// Feedback (base -> host) frames corrupted.
    CorruptFeedback,
}

/// A CAN bus node with a fault injector in front of it: what the node receives (`try_recv`,
/// the hosts' commands) and what it sends (`send`, the base's feedback) pass the fault in
/// effect. The world puts the simulated base behind one; everyone else on the bus sees a base
/// whose link misbehaves.
pub struct FaultyBus<B> {
    inner: B,
    fault: CanFault,
    now: Duration,
    rng: ChaCha8Rng,
    /// Frames on their way in (to the node) and out (to the bus), with their due time.
    inbound: VecDeque<(Duration, CanFrame)>,
    outbound: VecDeque<(Duration, CanFrame)>,
    held_in: Option<CanFrame>,
    held_out: Option<CanFrame>,
    counts: CanFaultCounts,
    monitor: CommandMonitor,
    /// The base's limits the normalised commands are scaled by (m/s, rad/s).
    limits: (f64, f64),
}

impl<B: CanBus> FaultyBus<B> {
    /// Wraps `inner`; no fault until [`set_fault`](Self::set_fault). `limits`: the base's
    /// velocity and yaw-rate limits (for the command monitor).
    pub fn new(inner: B, seed: u64, limits: (f64, f64)) -> Self {
        Self {
            inner,
            fault: CanFault::None,
            now: Duration::ZERO,
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0xfa17_b005),
            inbound: VecDeque::new(),
            outbound: VecDeque::new(),
            held_in: None,
            held_out: None,
            counts: CanFaultCounts::default(),
            monitor: CommandMonitor::default(),
            limits,
        }
    }

    /// The base's velocity and yaw-rate limits now (they are NVM settings the host may write).
    pub fn set_limits(&mut self, limits: (f64, f64)) {
        self.limits = limits;
    }

    /// Marks now (the fault's instant) for [`CommandMonitor::first_zero_after_mark_s`].
    pub fn mark(&mut self) {
        self.monitor.mark_s = Some(self.now.as_secs_f64());
    }

    /// The fault from now on.
    pub fn set_fault(&mut self, fault: CanFault) {
        self.fault = fault;
    }

    /// The fault in effect.
    pub fn fault(&self) -> CanFault {
        self.fault
    }

    /// What the injector did so far.
    pub fn counts(&self) -> CanFaultCounts {
        self.counts
    }

    /// The motion commands seen so far.
    pub fn monitor(&self) -> CommandMonitor {
        self.monitor
    }

    /// Sets the time (simulated) and sends the outbound frames that are due.
    pub fn set_now(&mut self, now: Duration) -> Result<(), SendError> {
        self.now = now;
        while self.outbound.front().is_some_and(|(due, _)| *due <= now) {
            if let Some((_, f)) = self.outbound.pop_front() {
                self.inner.send(&f)?;
            }
        }
        Ok(())
    }

    fn observe_command(&mut self, frame: &CanFrame) {
        let CanId::Standard(id) = frame.id() else {
            return;
        };
        if id != MOTION_ID {
            return;
        }
        let Ok(raw) = RawFrame::new(id, frame.data()) else {
            return;
        };
        let m = &mut self.monitor;
        m.frames += 1;
        match MotionCommand::decode(&raw) {
            Ok(c) => {
                let v = f64::from(c.velocity()) * self.limits.0;
                let w = f64::from(c.yaw_rate()) * self.limits.1;
                m.max_speed_mps = m.max_speed_mps.max(v.abs());
                m.max_yaw_rate_radps = m.max_yaw_rate_radps.max(w.abs());
                m.last = (v, w);
                if v == 0.0 && w == 0.0 {
                    m.zero_since_s.get_or_insert(self.now.as_secs_f64());
                    if m.mark_s.is_some() {
                        m.first_zero_after_mark_s
                            .get_or_insert(self.now.as_secs_f64());
                    }
                } else {
                    m.zero_since_s = None;
                }
            }
            Err(_) => m.malformed += 1,
        }
    }

    /// Applies the fault to one frame going `inbound` (to the node) or out; returns the frames
    /// that pass, with their delays.
    fn apply(&mut self, frame: CanFrame, inbound: bool) -> heapless::Vec<(Duration, CanFrame), 2> {
        let mut out = heapless::Vec::new();
        match self.fault {
            CanFault::None => {
                let _ = out.push((Duration::ZERO, frame));
            }
            CanFault::Loss { p } => {
                if self.rng.random::<f64>() < p {
                    self.counts.dropped += 1;
                } else {
                    let _ = out.push((Duration::ZERO, frame));
                }
            }
            CanFault::Duplicate => {
                self.counts.duplicated += 1;
                let _ = out.push((Duration::ZERO, frame));
                let _ = out.push((Duration::ZERO, frame));
            }
            CanFault::Delay { min, max } => {
                self.counts.delayed += 1;
                let span = max.saturating_sub(min).as_secs_f64();
                let d = min + Duration::from_secs_f64(self.rng.random::<f64>() * span);
                let _ = out.push((d, frame));
            }
            CanFault::Reorder => {
                let held = if inbound {
                    &mut self.held_in
                } else {
                    &mut self.held_out
                };
                match held.take() {
                    None => *held = Some(frame),
                    Some(first) => {
                        self.counts.reordered += 1;
                        let _ = out.push((Duration::ZERO, frame));
                        let _ = out.push((Duration::ZERO, first));
                    }
                }
            }
            CanFault::CorruptFeedback if !inbound => {
                self.counts.corrupted += 1;
                let mut data = [0u8; 8];
                let len = frame.data().len();
                data[..len].copy_from_slice(frame.data());
                for b in &mut data[..len] {
                    *b ^= self.rng.random::<u8>() | 1;
                }
                match CanFrame::new(frame.id(), &data[..len]) {
                    Ok(f) => {
                        let _ = out.push((Duration::ZERO, f));
                    }
                    Err(_) => {
                        let _ = out.push((Duration::ZERO, frame));
                    }
                }
            }
            CanFault::CorruptFeedback => {
                let _ = out.push((Duration::ZERO, frame));
            }
        }
        out
    }
}

impl<B: CanBus> CanBus for FaultyBus<B> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        for (delay, f) in self.apply(*frame, false) {
            if delay.is_zero() && self.outbound.is_empty() {
                self.inner.send(&f)?;
            } else {
                insert_due(&mut self.outbound, self.now + delay, f);
            }
        }
        Ok(())
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        // Everything that arrived goes through the fault first, in arrival order.
        while let Some(frame) = self.inner.try_recv()? {
            self.observe_command(&frame);
            for (delay, f) in self.apply(frame, true) {
                insert_due(&mut self.inbound, self.now + delay, f);
            }
        }
        if self
            .inbound
            .front()
            .is_some_and(|(due, _)| *due <= self.now)
        {
            return Ok(self.inbound.pop_front().map(|(_, f)| f));
        }
        Ok(None)
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, RecvError> {
        if let Some(f) = self.try_recv()? {
            return Ok(Some(f));
        }
        match self.inner.recv_timeout(timeout)? {
            Some(frame) => {
                self.observe_command(&frame);
                for (delay, f) in self.apply(frame, true) {
                    insert_due(&mut self.inbound, self.now + delay, f);
                }
                self.try_recv()
            }
            None => Ok(None),
        }
    }
}

/// Keeps `queue` ordered by due time (stable: equal times keep their order).
fn insert_due(queue: &mut VecDeque<(Duration, CanFrame)>, due: Duration, frame: CanFrame) {
    let at = queue.partition_point(|(d, _)| *d <= due);
    queue.insert(at, (due, frame));
}

#[cfg(test)]
mod tests {
    use super::*;
    use can_bus::MemoryBus;

    fn frame(i: u8) -> CanFrame {
        CanFrame::new(CanId::Standard(0x502), &[i; 8]).unwrap()
    }

    #[test]
    fn specs_parse_and_print_back() {
        for kind in FaultKind::ALL {
            let spec: FaultSpec = kind.name().parse().unwrap();
            assert_eq!(spec.trigger, kind.default_trigger());
            assert_eq!(spec.to_string().parse::<FaultSpec>().unwrap(), spec);
        }
        let s: FaultSpec = "can-silent@12.5".parse().unwrap();
        assert_eq!(s.trigger, Trigger::At(Duration::from_millis(12_500)));
        assert!(matches!(
            "can-sillent".parse::<FaultSpec>(),
            Err(FaultParseError::Kind(_))
        ));
        assert!(matches!(
            "can-silent@soon".parse::<FaultSpec>(),
            Err(FaultParseError::Trigger(_))
        ));
        assert!("can-silent@-1".parse::<FaultSpec>().is_err());
    }

    /// Frames the far end receives after `sent` went through the injector outbound.
    fn through(fault: CanFault, sent: &[CanFrame], steps: u32) -> Vec<CanFrame> {
        let bus = MemoryBus::new();
        let mut far = bus.join();
        let mut faulty = FaultyBus::new(bus.join(), 7, (1.0, 1.0));
        faulty.set_fault(fault);
        for f in sent {
            faulty.send(f).unwrap();
        }
        let mut got = Vec::new();
        for k in 0..steps {
            faulty.set_now(Duration::from_millis(u64::from(k))).unwrap();
            while let Some(f) = far.try_recv().unwrap() {
                got.push(f);
            }
        }
        got
    }

    #[test]
    fn each_fault_does_what_it_says_to_outbound_frames() {
        let sent: Vec<CanFrame> = (0..6).map(frame).collect();
        assert_eq!(through(CanFault::None, &sent, 1), sent);
        assert!(through(CanFault::Loss { p: 1.0 }, &sent, 1).is_empty());
        let dup = through(CanFault::Duplicate, &sent, 1);
        assert_eq!(dup.len(), 12);
        assert_eq!(dup[0], dup[1]);
        let swapped = through(CanFault::Reorder, &sent, 1);
        assert_eq!(
            swapped,
            vec![sent[1], sent[0], sent[3], sent[2], sent[5], sent[4]]
        );
        let corrupt = through(CanFault::CorruptFeedback, &sent, 1);
        assert_eq!(corrupt.len(), 6);
        assert!(corrupt.iter().zip(&sent).all(|(c, s)| c.data() != s.data()));
        let delay = CanFault::Delay {
            min: Duration::from_millis(10),
            max: Duration::from_millis(50),
        };
        // Nothing before 10 ms, everything by 50 ms.
        assert!(through(delay, &sent, 10).is_empty());
        assert_eq!(through(delay, &sent, 51).len(), 6);
    }

    #[test]
    fn inbound_commands_are_monitored_before_the_fault_and_delayed_by_it() {
        let bus = MemoryBus::new();
        let mut host = bus.join();
        let mut faulty = FaultyBus::new(bus.join(), 1, (1.2, 2.0));
        faulty.set_fault(CanFault::Delay {
            min: Duration::from_millis(20),
            max: Duration::from_millis(20),
        });
        let cmd = |v, w| rmp_base_frame(MotionCommand::new(v, w).unwrap().encode());
        host.send(&cmd(0.5, -0.25)).unwrap();
        faulty.set_now(Duration::ZERO).unwrap();
        assert_eq!(faulty.try_recv().unwrap(), None, "held back");
        let m = faulty.monitor();
        assert_eq!(m.frames, 1);
        assert!((m.max_speed_mps - 0.6).abs() < 1e-6);
        assert!((m.max_yaw_rate_radps - 0.5).abs() < 1e-6);
        faulty.set_now(Duration::from_millis(20)).unwrap();
        assert!(faulty.try_recv().unwrap().is_some());
        host.send(&cmd(0.0, 0.0)).unwrap();
        faulty.set_now(Duration::from_millis(40)).unwrap();
        let _ = faulty.try_recv().unwrap();
        assert_eq!(faulty.monitor().zero_since_s, Some(0.04));
    }

    fn rmp_base_frame(raw: RawFrame) -> CanFrame {
        CanFrame::new(CanId::Standard(raw.id()), raw.data()).unwrap()
    }
}
