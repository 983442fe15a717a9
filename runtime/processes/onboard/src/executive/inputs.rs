//! Who may command the executive (docs/security.md): its command inputs (plans, localisation
//! fixes, the planner's heartbeats) are read through [`AdmittingSubscriber`]s that accept only
//! the node the deployment names for each, in its own process, with an advancing sequence
//! (the operator's enable: a new process of the operator's tool once the last has left).
//! Everything else is refused: counted, logged, reported on `events` ([`EventKind::InputRefused`],
//! at most one event per input and kind of refusal a second, with the count since the
//! last) and never handed to the
//! mission core. What is accepted is then checked against the map and the robot file as before
//! (`plan_check`, the localiser's gates).
//!
//! A new command input is one field here, one line in [`ExecutiveInputs::open`], and one
//! `impl Sequenced` for its message.

use std::time::Duration;

use grop_ipc::{
    Admission, AdmittingSubscriber, BasePoseMsg, EventKind, EventMsg, HeartbeatMsg, IpcNode,
    OperatorEnableMsg, PortError, ProcessRole, Refusal, TaskPlanMsg, TopicPublisher,
};

/// Node names allowed to publish each command input (the deployment's `[inputs]`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputSources {
    /// `plan/task`: the planning node.
    pub plans: String,
    /// `health` with the planner's role: the planning node.
    pub planner_heartbeats: String,
    /// `base/pose`: the localiser (the HIL world in simulation).
    pub fixes: String,
    /// `operator/enable`: the operator's tool (`grop enable`; the HIL world in simulation).
    /// A new process of it is accepted once the one before has left (each enable is a new
    /// `grop enable`).
    pub operator: String,
}

impl Default for InputSources {
    /// The onboard binaries' node names: `grop-planner`; fixes from `grop-localiser`.
    fn default() -> Self {
        Self {
            plans: "grop-planner".into(),
            planner_heartbeats: "grop-planner".into(),
            fixes: "grop-localiser".into(),
            operator: "grop-enable".into(),
        }
    }
}

impl InputSources {
    /// Every input from one node (a test harness that plays planner and localiser).
    pub fn all(node: &str) -> Self {
        Self {
            plans: node.into(),
            planner_heartbeats: node.into(),
            fixes: node.into(),
            operator: node.into(),
        }
    }
}

/// Refusals of one input not yet reported.
struct RefusalReport {
    topic: &'static str,
    refused: u64,
    pending: u64,
    last: Option<Refusal>,
    next_report: Duration,
}

impl RefusalReport {
    fn new(topic: &'static str) -> Self {
        Self {
            topic,
            refused: 0,
            pending: 0,
            last: None,
            next_report: Duration::ZERO,
        }
    }
}

/// The executive's command inputs behind their admission checks.
pub struct ExecutiveInputs {
    plans: AdmittingSubscriber<TaskPlanMsg>,
    fixes: AdmittingSubscriber<BasePoseMsg>,
    heartbeats: AdmittingSubscriber<HeartbeatMsg>,
    enables: AdmittingSubscriber<OperatorEnableMsg>,
    /// Its own publisher on `events` (its own sequence, beside the mission core's).
    events: TopicPublisher<EventMsg>,
    event_seq: u64,
    /// Per input (plans, fixes, heartbeats, enables) and kind of refusal ([`refusal_kind`]).
    reports: [[RefusalReport; REFUSAL_KINDS]; 4],
}

/// Kinds of [`Refusal`], each reported on its own (one kind must not hide another).
const REFUSAL_KINDS: usize = 6;

fn refusal_kind(refusal: &Refusal) -> usize {
    match refusal {
        Refusal::UnknownSender => 0,
        Refusal::NotAllowed { .. } => 1,
        Refusal::Second { .. } => 2,
        Refusal::PidMismatch { .. } => 3,
        Refusal::NotAdvancing { .. } => 4,
        Refusal::Successor { .. } => 5,
    }
}

const PLANS: usize = 0;
const FIXES: usize = 1;
const HEARTBEATS: usize = 2;
const ENABLES: usize = 3;

/// Refusals of one input are reported at most this often.
const REPORT_EVERY: Duration = Duration::from_secs(1);

fn is_planner(h: &HeartbeatMsg) -> bool {
    h.role() == Ok(ProcessRole::Planner)
}

impl ExecutiveInputs {
    /// Opens the inputs in `node`, accepting each from its node in `sources`.
    pub fn open(node: &IpcNode, sources: &InputSources) -> Result<Self, PortError> {
        Ok(Self {
            plans: node.admitting_subscriber(&sources.plans, |_| true)?,
            fixes: node.admitting_subscriber(&sources.fixes, |_| true)?,
            heartbeats: node.admitting_subscriber(&sources.planner_heartbeats, is_planner)?,
            enables: node
                .admitting_subscriber(&sources.operator, |_| true)?
                .accept_successors(),
            events: node.publisher()?,
            event_seq: 0,
            reports: [
                "plan/task",
                "base/pose",
                "health (planner)",
                "operator/enable",
            ]
            .map(|topic| std::array::from_fn(|_| RefusalReport::new(topic))),
        })
    }

    /// Messages refused so far, all inputs.
    pub fn refused(&self) -> u64 {
        self.reports.iter().flatten().map(|r| r.refused).sum()
    }

    /// Reads up to `max` accepted fixes into `out` (cleared first).
    pub fn read_fixes(&mut self, now: Duration, out: &mut Vec<BasePoseMsg>, max: usize) {
        out.clear();
        while out.len() < max {
            match self.fixes.try_recv() {
                Ok(Some(Admission::Accepted(fix))) => out.push(*fix),
                Ok(Some(Admission::Refused(r))) => self.refuse(FIXES, r, now),
                _ => break,
            }
        }
    }

    /// Reads the accepted plans into `out` (cleared first), keeping the newest `max`.
    pub fn read_plans(&mut self, now: Duration, out: &mut Vec<TaskPlanMsg>, max: usize) {
        out.clear();
        loop {
            match self.plans.try_recv() {
                Ok(Some(Admission::Accepted(plan))) => {
                    if out.len() == max {
                        // Newest last: drop the oldest.
                        out.remove(0);
                    }
                    out.push(*plan);
                }
                Ok(Some(Admission::Refused(r))) => self.refuse(PLANS, r, now),
                _ => break,
            }
        }
    }

    /// Counts the planner's accepted heartbeats unread so far.
    pub fn read_planner_heartbeats(&mut self, now: Duration) -> u32 {
        let mut beats = 0u32;
        loop {
            match self.heartbeats.try_recv() {
                Ok(Some(Admission::Accepted(_))) => beats = beats.saturating_add(1),
                Ok(Some(Admission::Refused(r))) => self.refuse(HEARTBEATS, r, now),
                _ => return beats,
            }
        }
    }

    /// The next accepted operator's enable unread so far, if one is.
    pub fn read_enable(&mut self, now: Duration) -> Option<OperatorEnableMsg> {
        loop {
            match self.enables.try_recv() {
                Ok(Some(Admission::Accepted(enable))) => return Some(*enable),
                Ok(Some(Admission::Refused(r))) => self.refuse(ENABLES, r, now),
                _ => return None,
            }
        }
    }

    /// Reports refusals held back by the rate limit once their time has come.
    pub fn report_pending(&mut self, now: Duration) {
        for input in 0..self.reports.len() {
            for kind in 0..REFUSAL_KINDS {
                let r = &self.reports[input][kind];
                if r.pending > 0 && now >= r.next_report {
                    self.report(input, kind, now);
                }
            }
        }
    }

    fn refuse(&mut self, input: usize, refusal: Refusal, now: Duration) {
        let kind = refusal_kind(&refusal);
        let r = &mut self.reports[input][kind];
        r.refused += 1;
        r.pending += 1;
        r.last = Some(refusal);
        if now >= r.next_report {
            self.report(input, kind, now);
        }
    }

    fn report(&mut self, input: usize, kind: usize, now: Duration) {
        let r = &mut self.reports[input][kind];
        let Some(last) = r.last.take() else { return };
        let detail = format!("{} refused x{}: {last}", r.topic, r.pending);
        log::warn!("input refused: {detail} ({} in all)", r.refused);
        r.pending = 0;
        r.next_report = now + REPORT_EVERY;
        self.event_seq += 1;
        let mut event = EventMsg::new(
            EventKind::InputRefused,
            u64::try_from(now.as_nanos()).unwrap_or(u64::MAX),
            &detail,
        )
        .with_source(ProcessRole::Executive);
        event.seq = self.event_seq;
        if let Err(e) = self.events.publish(&event) {
            log::warn!("input refused: reporting it failed: {e}");
        }
    }
}
