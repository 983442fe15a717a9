//! The controller's sockets: RTDE, dashboard, primary/secondary/real-time, gripper; and the
//! 500 Hz control thread that steps the [`RobotModel`] and publishes snapshots.
//!
//! Threads: one control thread (none with `Stepping::External`: the owner steps, see
//! `stepping`); one accept thread per port; per connection a reader thread
//! (requests, scripts) and, where the controller streams, a writer thread that waits for the
//! next published snapshot and writes only the newest one, so a slow or silent client (ur_rtde
//! never reads 30003) never holds up the control loop or other clients.

use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ur5e::rtde::wire::{
    self, PackageType, RtdeType, RtdeValue, SetupField, TextLevel, TextMessage,
};

use crate::SimConfig;
use crate::external_control::{
    ExternalControlScript, REVERSE_MESSAGE_INTS, SCRIPT_COMMAND_INTS, TRAJECTORY_POINT_INTS,
    decode_ints, encode_ints, is_external_control, parse_external_control,
};
use crate::fields::{InputTable, OutputField, resolve_output};
use crate::primary;
use crate::robot::{RobotModel, Snapshot};
use crate::stepping::Stepping;
use crate::stepping::{self, AckSlot, ReaderSync, STEP_WAIT, StepReport, lock};
use crate::urscript::{is_rtde_control, parse_program, parse_rtde_control};

mod dashboard;
mod external;
mod gripper;
mod rtde;
mod scripts;

use dashboard::*;
use external::*;
use gripper::*;
use rtde::*;
use scripts::*;

/// The robot and its RTDE inputs, behind one lock.
#[derive(Debug)]
pub(crate) struct Controller {
    pub robot: RobotModel,
    pub inputs: InputTable,
}

impl Controller {
    /// Side effects of input variables (speed slider, digital outputs) after a write.
    fn apply_io(&mut self) {
        let get = |name: &str| self.inputs.index_of(name).map(|i| self.inputs.value(i));
        if let (Some(RtdeValue::Uint32(mask)), Some(RtdeValue::Double(f))) =
            (get("speed_slider_mask"), get("speed_slider_fraction"))
        {
            if mask & 1 == 1 {
                self.robot.set_speed_fraction(f);
            }
        }
        let mut outputs = Vec::new();
        for (mask, value, shift) in [
            ("standard_digital_output_mask", "standard_digital_output", 0),
            (
                "configurable_digital_output_mask",
                "configurable_digital_output",
                8,
            ),
            ("tool_digital_output_mask", "tool_digital_output", 16),
        ] {
            if let (Some(RtdeValue::Uint8(m)), Some(RtdeValue::Uint8(v))) = (get(mask), get(value))
            {
                outputs.push((u64::from(m) << shift, u64::from(v) << shift));
            }
        }
        for (m, v) in outputs {
            self.robot.set_digital_outputs(m, v);
        }
    }
}

/// The newest snapshot, with its sequence number.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Published {
    pub seq: u64,
    pub snap: Snapshot,
}

/// State shared by all threads.
pub(crate) struct Shared {
    pub cfg: SimConfig,
    pub ctl: Mutex<Controller>,
    pub published: Mutex<Published>,
    pub tick: Condvar,
    pub shutdown: AtomicBool,
    pub next_conn: AtomicU64,
    /// Open connections by port kind, so they can be cut (fault injection, shutdown).
    pub conns: Mutex<Vec<(PortKind, u64, TcpStream)>>,
    pub overruns: AtomicU64,
    /// Reader threads whose input must be applied before an external step (RTDE, URScript).
    pub readers: Mutex<Vec<(u64, Arc<ReaderSync>)>>,
    /// RTDE streamers' acknowledgements, and the condvar they notify.
    pub acks: Mutex<Vec<AckSlot>>,
    pub acked: Condvar,
    /// One external step at a time.
    pub step_lock: Mutex<()>,
    /// Link faults injected at the controller's sockets ([`crate::LinkFaults`]).
    pub link_faults: crate::LinkFaults,
}

/// Which socket a connection came in on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PortKind {
    /// 30004.
    Rtde,
    /// 29999.
    Dashboard,
    /// 30001.
    Primary,
    /// 30002.
    Secondary,
    /// 30003.
    Realtime,
    /// 63352.
    Gripper,
}

impl Shared {
    pub fn new(cfg: SimConfig) -> Self {
        let mut robot = RobotModel::new(cfg.init);
        robot.gripper.object_width_m = cfg.gripper_object_width_m;
        let snap = robot.snapshot();
        Self {
            cfg,
            ctl: Mutex::new(Controller {
                robot,
                inputs: InputTable::new(),
            }),
            published: Mutex::new(Published { seq: 0, snap }),
            tick: Condvar::new(),
            shutdown: AtomicBool::new(false),
            next_conn: AtomicU64::new(1),
            conns: Mutex::new(Vec::new()),
            overruns: AtomicU64::new(0),
            readers: Mutex::new(Vec::new()),
            acks: Mutex::new(Vec::new()),
            acked: Condvar::new(),
            step_lock: Mutex::new(()),
            link_faults: crate::LinkFaults::default(),
        }
    }

    /// Advances the model by one period and publishes the snapshot; returns its sequence
    /// number (= the controller cycle).
    fn step_model(&self) -> Published {
        let dt = 1.0 / self.cfg.rate_hz;
        let snap = {
            let mut ctl = lock(&self.ctl);
            let Controller { robot, inputs } = &mut *ctl;
            robot.step(dt, inputs);
            robot.snapshot()
        };
        let published = {
            let mut p = lock(&self.published);
            p.seq += 1;
            p.snap = snap;
            *p
        };
        self.tick.notify_all();
        published
    }

    /// One external step (see `stepping`): apply pending input, advance, wait until every RTDE
    /// streamer has handled the new cycle.
    pub fn step_external(&self) -> StepReport {
        let _one_at_a_time = lock(&self.step_lock);
        let inputs_lagging = stepping::wait_drained(&self.readers);
        let p = self.step_model();
        let guard = lock(&self.acks);
        let (guard, _) = self
            .acked
            .wait_timeout_while(guard, STEP_WAIT, |acks| {
                acks.iter().any(|a| a.handled < p.seq) && !self.stopping()
            })
            .unwrap_or_else(|e| e.into_inner());
        StepReport {
            cycle: p.snap.cycle,
            time_s: p.snap.time_s,
            rtde_packages_written: guard.iter().filter(|a| a.written == p.seq).count(),
            rtde_lagging: guard.iter().filter(|a| a.handled < p.seq).count(),
            inputs_lagging,
        }
    }

    /// Registers an RTDE streamer; returns the sequence number it starts after. Under the
    /// `published` lock, so no step can fall between reading the number and registering.
    fn add_streamer(&self, conn: u64) -> u64 {
        let p = lock(&self.published);
        lock(&self.acks).push(AckSlot {
            conn,
            handled: p.seq,
            written: 0,
        });
        p.seq
    }

    /// A streamer has handled `seq` (and written it, if `wrote`).
    fn ack(&self, conn: u64, seq: u64, wrote: bool) {
        {
            let mut acks = lock(&self.acks);
            if let Some(a) = acks.iter_mut().find(|a| a.conn == conn) {
                a.handled = seq;
                if wrote {
                    a.written = seq;
                }
            }
        }
        self.acked.notify_all();
    }

    fn remove_streamer(&self, conn: u64) {
        lock(&self.acks).retain(|a| a.conn != conn);
        self.acked.notify_all();
    }

    fn add_reader(&self, conn: u64, stream: &TcpStream) -> io::Result<Arc<ReaderSync>> {
        let sync = Arc::new(ReaderSync::new(stream)?);
        lock(&self.readers).push((conn, Arc::clone(&sync)));
        Ok(sync)
    }

    fn remove_reader(&self, conn: u64) {
        lock(&self.readers).retain(|(c, _)| *c != conn);
    }

    fn stopping(&self) -> bool {
        self.shutdown.load(Ordering::Acquire)
    }

    /// Waits for a snapshot newer than `seen`; `None` on shutdown or after `timeout`.
    fn wait_newer(&self, seen: u64, timeout: Duration) -> Option<Published> {
        let guard = lock(&self.published);
        let (guard, _) = self
            .tick
            .wait_timeout_while(guard, timeout, |p| p.seq == seen && !self.stopping())
            .unwrap_or_else(|e| e.into_inner());
        (guard.seq != seen).then_some(*guard)
    }

    fn register(&self, kind: PortKind, stream: &TcpStream) -> u64 {
        let id = self.next_conn.fetch_add(1, Ordering::Relaxed);
        if let Ok(clone) = stream.try_clone() {
            lock(&self.conns).push((kind, id, clone));
        }
        id
    }

    fn unregister(&self, id: u64) {
        lock(&self.conns).retain(|(_, i, _)| *i != id);
    }

    /// Cuts every open connection of `kind` (or all when `None`).
    pub fn cut(&self, kind: Option<PortKind>) -> usize {
        let conns = lock(&self.conns);
        let mut n = 0;
        for (k, _, s) in conns.iter() {
            if kind.is_none_or(|want| want == *k) {
                let _ = s.shutdown(Shutdown::Both);
                n += 1;
            }
        }
        n
    }
}

/// The control thread: steps the model at `rate_hz` on absolute deadlines.
pub(crate) fn control_loop(shared: Arc<Shared>) {
    let period = Duration::from_secs_f64(1.0 / shared.cfg.rate_hz);
    let mut next = Instant::now() + period;
    while !shared.stopping() {
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        }
        shared.step_model();
        next += period;
        // Far behind (machine stalled): skip ahead rather than burst to catch up.
        let now = Instant::now();
        if now > next + 5 * period {
            shared.overruns.fetch_add(1, Ordering::Relaxed);
            next = now + period;
        }
    }
    shared.tick.notify_all();
}

/// Binds a listener and spawns its accept thread.
pub(crate) fn listen(
    shared: &Arc<Shared>,
    kind: PortKind,
    port: u16,
) -> io::Result<(SocketAddr, JoinHandle<()>)> {
    let listener = TcpListener::bind(SocketAddr::new(shared.cfg.bind_ip, port))?;
    let addr = listener.local_addr()?;
    let shared = Arc::clone(shared);
    let handle = std::thread::Builder::new()
        .name(format!("sim-ur5e-accept-{kind:?}"))
        .spawn(move || {
            for stream in listener.incoming() {
                if shared.stopping() {
                    break;
                }
                let stream = match stream {
                    Ok(s) => s,
                    Err(e) => {
                        log::warn!("sim-ur5e {kind:?}: accept failed: {e}");
                        continue;
                    }
                };
                let _ = stream.set_nodelay(true);
                let shared = Arc::clone(&shared);
                let spawned = std::thread::Builder::new()
                    .name(format!("sim-ur5e-{kind:?}"))
                    .spawn(move || {
                        let id = shared.register(kind, &stream);
                        let result = match kind {
                            PortKind::Rtde => rtde_connection(&shared, id, stream),
                            PortKind::Dashboard => dashboard_connection(&shared, stream),
                            PortKind::Primary | PortKind::Secondary | PortKind::Realtime => {
                                script_connection(&shared, id, kind, stream)
                            }
                            PortKind::Gripper => gripper_connection(&shared, stream),
                        };
                        if let Err(e) = result {
                            log::debug!("sim-ur5e {kind:?} connection {id} ended: {e}");
                        }
                        shared.unregister(id);
                    });
                if let Err(e) = spawned {
                    log::error!("sim-ur5e {kind:?}: cannot spawn connection thread: {e}");
                }
            }
        })?;
    Ok((addr, handle))
}

#[cfg(test)]
mod tests {
    use super::take_program;

    #[test]
    fn programs_are_cut_at_their_end_line() {
        let mut s = String::from("def a():\n  sleep(1)\nend\nstopj(2)\npartial");
        assert_eq!(take_program(&mut s).unwrap(), "def a():\n  sleep(1)\nend\n");
        assert_eq!(take_program(&mut s).unwrap(), "stopj(2)\n");
        assert_eq!(take_program(&mut s), None);
        assert_eq!(s, "partial");
        let mut s = String::from("def a():\n  sleep(1)\n");
        assert_eq!(take_program(&mut s), None);
    }
}
