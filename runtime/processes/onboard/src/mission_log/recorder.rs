//! What the recorder does: at each of its cycles, take everything published since the last one
//! on every topic and every frame on the CAN bus, encode it and queue it for the writer. Camera
//! frames are kept at the rate the planner uses them: one per `camera_period`, plus any frame a
//! plan or heatmaps name that was not kept (the newest few frames wait in a small ring for that),
//! so a replay always has the frame each decision saw. The lidar's revolutions are kept at one
//! a second. With [`Recorder::with_views`] it also logs the channels in Foxglove's well-known
//! schemas that it derives from what it took ([`Views`]), after each drain's messages.

use std::collections::VecDeque;

use can_bus::CanBus;
use grop_ipc::{
    ArmIoMsg, ArmStateMsg, BasePoseMsg, BaseStateMsg, CameraFrameMsg, EventMsg, HeartbeatMsg,
    HeatmapsMsg, IpcNode, LoadRequestMsg, ReplanRequestMsg, TaskPlanMsg, Topic, TopicSubscriber,
};

use super::LogError;
use super::codec::{self, Channel};
use super::live::LiveFeed;
use super::views::Views;
use super::writer::{LogWriter, WriterSummary};

/// Time between two logged revolutions of the range sensor (ns of their stamps).
const SCAN_PERIOD_NS: u64 = 1_000_000_000;

/// Frames kept back in case a plan names them.
const CAMERA_RING: usize = 4;

/// Settings of the recorder.
#[derive(Debug, Clone, Copy)]
pub struct RecorderConfig {
    /// Keep at most one camera frame per this many ns (plus the frames plans name).
    pub camera_period_ns: u64,
}

impl Default for RecorderConfig {
    fn default() -> Self {
        Self {
            camera_period_ns: 1_000_000_000,
        }
    }
}

struct Subs {
    camera: TopicSubscriber<CameraFrameMsg>,
    heatmaps: TopicSubscriber<HeatmapsMsg>,
    plans: TopicSubscriber<TaskPlanMsg>,
    requests: TopicSubscriber<ReplanRequestMsg>,
    loads: TopicSubscriber<LoadRequestMsg>,
    poses: TopicSubscriber<BasePoseMsg>,
    base: TopicSubscriber<BaseStateMsg>,
    arm: TopicSubscriber<ArmStateMsg>,
    arm_io: TopicSubscriber<ArmIoMsg>,
    events: TopicSubscriber<EventMsg>,
    health: TopicSubscriber<HeartbeatMsg>,
    enables: TopicSubscriber<grop_ipc::OperatorEnableMsg>,
    scans: TopicSubscriber<grop_ipc::ScanMsg>,
    truth: TopicSubscriber<grop_ipc::TruthMsg>,
}

/// A message taken from a topic: its sort key, its encoding and a copy.
struct Taken<T> {
    stamp: u64,
    seq: u64,
    data: Vec<u8>,
    msg: T,
}

/// A frame not (yet) logged.
struct HeldFrame {
    frame_id: u64,
    log_time: u64,
    stamp: u64,
    msg: Box<CameraFrameMsg>,
}

/// The recorder's state (see the module docs).
pub struct Recorder {
    subs: Subs,
    bus: Option<Box<dyn CanBus + Send>>,
    writer: LogWriter,
    config: RecorderConfig,
    last_camera_stamp: Option<u64>,
    last_scan_stamp: Option<u64>,
    held: VecDeque<HeldFrame>,
    /// Recently logged frame ids.
    logged_frames: VecDeque<u64>,
    receive_errors: u64,
    /// The live view's feed, when it runs.
    live: Option<LiveFeed>,
    /// The channels in Foxglove's well-known schemas, when the recorder has the map.
    views: Option<Views>,
}

fn port(e: impl std::fmt::Display) -> LogError {
    LogError::Source(e.to_string())
}

impl Recorder {
    /// Subscribes to every topic in `node`'s namespace (and listens on `bus`, if given).
    pub fn new(
        node: &IpcNode,
        bus: Option<Box<dyn CanBus + Send>>,
        writer: LogWriter,
        config: RecorderConfig,
    ) -> Result<Self, LogError> {
        Ok(Self {
            subs: Subs {
                camera: node.subscriber().map_err(port)?,
                heatmaps: node.subscriber().map_err(port)?,
                plans: node.subscriber().map_err(port)?,
                requests: node.subscriber().map_err(port)?,
                loads: node.subscriber().map_err(port)?,
                poses: node.subscriber().map_err(port)?,
                base: node.subscriber().map_err(port)?,
                arm: node.subscriber().map_err(port)?,
                arm_io: node.subscriber().map_err(port)?,
                events: node.subscriber().map_err(port)?,
                health: node.subscriber().map_err(port)?,
                enables: node.subscriber().map_err(port)?,
                scans: node.subscriber().map_err(port)?,
                truth: node.subscriber().map_err(port)?,
            },
            bus,
            writer,
            config,
            last_camera_stamp: None,
            last_scan_stamp: None,
            held: VecDeque::with_capacity(CAMERA_RING),
            logged_frames: VecDeque::with_capacity(16),
            receive_errors: 0,
            live: None,
            views: None,
        })
    }

    /// Also offers every message it logs to a live view (never waiting: see [`LiveFeed`]).
    pub fn with_live(mut self, live: LiveFeed) -> Self {
        self.live = Some(live);
        self
    }

    /// Also derives and logs the channels in Foxglove's well-known schemas (`/tf`, `/scene`,
    /// paths, the heatmaps' grid, events as log messages; see [`Views`]).
    pub fn with_views(mut self, views: Views) -> Self {
        self.views = Some(views);
        self
    }

    /// Queues one message for the log, and offers it to the live view first.
    fn emit(
        writer: &LogWriter,
        live: &mut Option<LiveFeed>,
        channel: Channel,
        log_time: u64,
        publish_time: u64,
        data: Vec<u8>,
    ) {
        if let Some(live) = live {
            live.offer(channel, log_time, &data);
        }
        writer.push(channel, log_time, publish_time, data);
    }

    /// Messages dropped by the writer so far.
    pub fn dropped(&self) -> u64 {
        self.writer.dropped()
    }

    /// Receive errors so far (a topic that could not be read; the message is lost).
    pub fn receive_errors(&self) -> u64 {
        self.receive_errors
    }

    fn drain_topic<T: Topic>(
        sub: &TopicSubscriber<T>,
        errors: &mut u64,
        mut each: impl FnMut(&T),
    ) -> usize {
        let mut n = 0;
        loop {
            match sub.try_recv() {
                Ok(Some(m)) => {
                    each(&m);
                    n += 1;
                }
                Ok(None) => return n,
                Err(_) => {
                    *errors += 1;
                    return n;
                }
            }
        }
    }

    /// Takes what `sub` has, encoded, in a canonical order: by stamp, then sequence number,
    /// then payload. iceoryx2 hands out the samples of several publishers connection by
    /// connection, in an order that depends on which process connected first; sorting makes
    /// the log the same for the same mission. Each message comes with its copy, for the views.
    fn take<T: Topic + Copy>(
        sub: &TopicSubscriber<T>,
        errors: &mut u64,
        key: fn(&T) -> (u64, u64),
        encode: fn(&T) -> Vec<u8>,
    ) -> Vec<Taken<T>> {
        let mut out = Vec::new();
        Self::drain_topic(sub, errors, |m| {
            let (stamp, seq) = key(m);
            out.push(Taken {
                stamp,
                seq,
                data: encode(m),
                msg: *m,
            });
        });
        out.sort_by(|a, b| (a.stamp, a.seq, &a.data).cmp(&(b.stamp, b.seq, &b.data)));
        out
    }

    /// Queues a batch taken by [`Recorder::take`] on `channel`; returns how many.
    fn emit_batch<T>(&mut self, channel: Channel, now_ns: u64, batch: &mut [Taken<T>]) -> usize {
        let n = batch.len();
        for t in batch.iter_mut() {
            let data = std::mem::take(&mut t.data);
            Self::emit(&self.writer, &mut self.live, channel, now_ns, t.stamp, data);
        }
        n
    }

    /// Takes everything published since the last call and queues it with log time `now_ns`.
    /// Returns how many messages it took.
    #[allow(clippy::too_many_lines, reason = "one entry per logged topic")]
    pub fn drain(&mut self, now_ns: u64) -> usize {
        if let Some(live) = &mut self.live {
            live.offer_time(now_ns);
        }
        let e = &mut self.receive_errors;
        // Inputs of the onboard processes first, then what they made of them.
        let mut poses = Self::take(
            &self.subs.poses,
            e,
            |m| (m.stamp_ns, m.seq),
            codec::encode_base_pose,
        );
        let mut health = Self::take(
            &self.subs.health,
            e,
            |m| (m.stamp_ns, m.seq),
            codec::encode_health,
        );
        let mut enables = Self::take(
            &self.subs.enables,
            e,
            |m| (m.stamp_ns, m.seq),
            codec::encode_enable,
        );
        let mut arm_io = Self::take(
            &self.subs.arm_io,
            e,
            |m| (m.stamp_ns, m.seq),
            codec::encode_arm_io,
        );
        let mut arm = Self::take(
            &self.subs.arm,
            e,
            |m| (m.stamp_ns, m.seq),
            codec::encode_arm_state,
        );
        let mut base = Self::take(
            &self.subs.base,
            e,
            |m| (m.stamp_ns, m.seq),
            codec::encode_base_state,
        );
        let mut requests = Self::take(
            &self.subs.requests,
            e,
            |m| (m.stamp_ns, m.request_id),
            codec::encode_plan_request,
        );
        let mut loads = Self::take(
            &self.subs.loads,
            e,
            |m| (m.stamp_ns, m.request_id),
            codec::encode_load_request,
        );
        let mut events = Self::take(
            &self.subs.events,
            e,
            |m| (m.stamp_ns, m.seq),
            codec::encode_event,
        );
        // One revolution of the range sensor per second (of ten).
        let mut scans = Self::take(
            &self.subs.scans,
            e,
            |m| (m.stamp_ns, m.seq),
            codec::encode_scan,
        );
        let last_scan = &mut self.last_scan_stamp;
        scans.retain(|t| {
            let due = last_scan.is_none_or(|last| t.stamp >= last + SCAN_PERIOD_NS);
            if due {
                *last_scan = Some(t.stamp);
            }
            due
        });
        // The simulated world's truth (HIL only), as it came.
        let mut truth = Self::take(
            &self.subs.truth,
            e,
            |m| (m.stamp_ns, m.seq),
            codec::encode_truth,
        );
        if let Some(views) = &mut self.views {
            for t in &truth {
                views.truth(&t.msg);
            }
            for t in &arm {
                views.arm_state(&t.msg);
            }
            for t in &base {
                views.base_state(&t.msg);
            }
            for t in &events {
                views.event(&t.msg);
            }
        }
        let mut n = 0;
        n += self.emit_batch(Channel::BasePose, now_ns, &mut poses);
        n += self.emit_batch(Channel::Health, now_ns, &mut health);
        n += self.emit_batch(Channel::OperatorEnable, now_ns, &mut enables);
        n += self.emit_batch(Channel::ArmIo, now_ns, &mut arm_io);
        n += self.emit_batch(Channel::ArmState, now_ns, &mut arm);
        n += self.emit_batch(Channel::BaseState, now_ns, &mut base);
        n += self.emit_batch(Channel::PlanRequest, now_ns, &mut requests);
        n += self.emit_batch(Channel::LoadRequest, now_ns, &mut loads);
        n += self.emit_batch(Channel::Events, now_ns, &mut events);
        n += self.emit_batch(Channel::Scan, now_ns, &mut scans);
        n += self.emit_batch(Channel::Truth, now_ns, &mut truth);
        if let Some(bus) = self.bus.as_mut() {
            loop {
                match bus.try_recv() {
                    Ok(Some(f)) => {
                        Self::emit(
                            &self.writer,
                            &mut self.live,
                            Channel::Can,
                            now_ns,
                            now_ns,
                            codec::encode_can(&f),
                        );
                        n += 1;
                    }
                    Ok(None) => break,
                    Err(_) => {
                        self.receive_errors += 1;
                        break;
                    }
                }
            }
        }
        n += self.drain_camera(now_ns);
        // Plans and heatmaps name their frame: log it first if it was held back.
        let mut named: Vec<u64> = Vec::new();
        let mut plans: Vec<(u64, Vec<u8>, Vec<u8>)> = Vec::new();
        let mut maps: Vec<(u64, Vec<u8>)> = Vec::new();
        let views = &mut self.views;
        n += Self::drain_topic(&self.subs.plans, &mut self.receive_errors, |m| {
            named.push(m.source_frame_id);
            plans.push((
                m.stamp_ns,
                codec::encode_task_plan(m),
                codec::encode_decision_timing(m),
            ));
            if let Some(v) = views.as_mut() {
                v.plan(m);
            }
        });
        n += Self::drain_topic(&self.subs.heatmaps, &mut self.receive_errors, |m| {
            named.push(m.source_frame_id);
            maps.push((m.stamp_ns, codec::encode_heatmaps(m)));
            if let Some(v) = views.as_mut() {
                v.heatmaps(m);
            }
        });
        for id in named {
            self.log_held_frame(id);
        }
        for (stamp, data) in maps {
            Self::emit(
                &self.writer,
                &mut self.live,
                Channel::Heatmaps,
                now_ns,
                stamp,
                data,
            );
        }
        for (stamp, plan, timing) in plans {
            Self::emit(
                &self.writer,
                &mut self.live,
                Channel::TaskPlan,
                now_ns,
                stamp,
                plan,
            );
            Self::emit(
                &self.writer,
                &mut self.live,
                Channel::DecisionTiming,
                now_ns,
                stamp,
                timing,
            );
        }
        // The views last: they follow from what came before.
        if let Some(views) = &mut self.views {
            for (channel, stamp, data) in views.take(now_ns) {
                Self::emit(&self.writer, &mut self.live, channel, now_ns, stamp, data);
            }
        }
        n
    }

    fn drain_camera(&mut self, now_ns: u64) -> usize {
        let mut n = 0;
        loop {
            let frame = match self.subs.camera.try_recv() {
                Ok(Some(f)) => f,
                Ok(None) => break,
                Err(_) => {
                    self.receive_errors += 1;
                    break;
                }
            };
            n += 1;
            let stamp = frame.header.stamp_ns;
            let due = self
                .last_camera_stamp
                .is_none_or(|last| stamp.saturating_sub(last) >= self.config.camera_period_ns);
            if due {
                self.last_camera_stamp = Some(stamp);
                self.mark_logged(frame.header.frame_id);
                if let Some(views) = &mut self.views {
                    views.camera(&frame);
                }
                Self::emit(
                    &self.writer,
                    &mut self.live,
                    Channel::CameraFrame,
                    now_ns,
                    stamp,
                    codec::encode_camera(&frame),
                );
                continue;
            }
            // Held back: reuse the oldest buffer when the ring is full.
            let mut held = if self.held.len() == CAMERA_RING {
                self.held.pop_front()
            } else {
                None
            }
            .unwrap_or_else(|| HeldFrame {
                frame_id: 0,
                log_time: 0,
                stamp: 0,
                msg: CameraFrameMsg::boxed_zeroed(),
            });
            held.frame_id = frame.header.frame_id;
            held.log_time = now_ns;
            held.stamp = stamp;
            match frame.image() {
                Ok(img) => {
                    let len = img.len();
                    held.msg.header = frame.header;
                    held.msg.pixels[..len].copy_from_slice(img);
                    self.held.push_back(held);
                }
                Err(_) => self.receive_errors += 1,
            }
        }
        n
    }

    fn mark_logged(&mut self, frame_id: u64) {
        if self.logged_frames.len() == self.logged_frames.capacity() {
            self.logged_frames.pop_front();
        }
        self.logged_frames.push_back(frame_id);
    }

    fn log_held_frame(&mut self, frame_id: u64) {
        if self.logged_frames.contains(&frame_id) {
            return;
        }
        if let Some(i) = self.held.iter().position(|h| h.frame_id == frame_id) {
            if let Some(h) = self.held.remove(i) {
                self.mark_logged(frame_id);
                if let Some(views) = &mut self.views {
                    views.camera(&h.msg);
                }
                Self::emit(
                    &self.writer,
                    &mut self.live,
                    Channel::CameraFrame,
                    h.log_time,
                    h.stamp,
                    codec::encode_camera(&h.msg),
                );
            }
        }
    }

    /// Takes what is left (with `Some(now)`) and closes the log. A recorder whose simulated
    /// clock is gone passes `None`: what arrives after the simulation ended happened at no
    /// simulated time, and logging it would make the same mission log differently.
    pub fn finish(mut self, now_ns: Option<u64>) -> Result<WriterSummary, LogError> {
        if let Some(now) = now_ns {
            self.drain(now);
        }
        self.writer.finish()
    }
}
