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
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
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
use crate::stepping::{self, AckSlot, ReaderSync, STEP_WAIT, StepReport};
use crate::urscript::{is_rtde_control, parse_program, parse_rtde_control};

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

/// Locks a mutex, recovering from a panicked holder (the data is plain state).
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
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

// ---------------------------------------------------------------------------------------------
// RTDE (30004)

#[derive(Debug, Default)]
struct RtdeConn {
    protocol: u16,
    started: bool,
    output: Option<OutputRecipe>,
    inputs: Vec<InputRecipe>,
    next_input_id: u8,
    closed: bool,
}

#[derive(Debug, Clone)]
struct OutputRecipe {
    id: u8,
    divisor: u64,
    fields: Vec<OutputField>,
}

#[derive(Debug, Clone)]
struct InputRecipe {
    id: u8,
    slots: Vec<usize>,
    types: Vec<RtdeType>,
}

fn send_package(w: &Mutex<TcpStream>, ty: PackageType, payload: &[u8]) -> io::Result<()> {
    let mut buf = Vec::with_capacity(payload.len() + wire::HEADER_LEN);
    wire::push_package(&mut buf, ty, payload)
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
    lock(w).write_all(&buf)
}

fn rtde_connection(shared: &Arc<Shared>, id: u64, stream: TcpStream) -> io::Result<()> {
    let writer = Arc::new(Mutex::new(stream.try_clone()?));
    let conn = Arc::new(Mutex::new(RtdeConn {
        protocol: 2,
        next_input_id: 1,
        ..RtdeConn::default()
    }));
    let sync = shared.add_reader(id, &stream)?;
    // Registered here, before the streamer thread exists: a client that starts the stream
    // before that thread is scheduled still gets the next cycle's package.
    let seen = shared.add_streamer(id);
    let streamer = {
        let (shared, writer, conn) = (Arc::clone(shared), Arc::clone(&writer), Arc::clone(&conn));
        std::thread::Builder::new()
            .name("sim-ur5e-rtde-out".into())
            .spawn(move || rtde_stream(&shared, id, seen, &writer, &conn))
    };
    let streamer = match streamer {
        Ok(s) => s,
        Err(e) => {
            shared.remove_streamer(id);
            shared.remove_reader(id);
            return Err(e);
        }
    };
    let result = rtde_requests(shared, id, stream, &sync, &writer, &conn);
    shared.remove_reader(id);
    lock(&conn).closed = true;
    lock(&shared.ctl).inputs.release(id);
    if let Ok(w) = writer.lock() {
        let _ = w.shutdown(Shutdown::Both);
    }
    shared.tick.notify_all();
    let _ = streamer.join();
    shared.remove_streamer(id);
    result
}

/// Writes the output recipe's data packages, newest snapshot only, and acknowledges every
/// sequence number it handled (for external stepping).
fn rtde_stream(
    shared: &Shared,
    id: u64,
    mut seen: u64,
    writer: &Mutex<TcpStream>,
    conn: &Mutex<RtdeConn>,
) {
    let mut buf = Vec::with_capacity(2048);
    loop {
        if shared.stopping() || lock(conn).closed {
            break;
        }
        let Some(p) = shared.wait_newer(seen, Duration::from_millis(100)) else {
            continue;
        };
        seen = p.seq;
        match rtde_write_package(shared, &p, &mut buf, writer, conn, false) {
            Ok(wrote) => shared.ack(id, p.seq, wrote),
            Err(()) => break,
        }
    }
    // A streamer that is gone must never hold up a step.
    shared.ack(id, u64::MAX, false);
}

/// Writes the data package of `p` if the connection is started and the cycle is due (output
/// divisor); `Ok(false)` when not due, `Err` when the connection cannot stream any more.
fn rtde_write_package(
    shared: &Shared,
    p: &Published,
    buf: &mut Vec<u8>,
    writer: &Mutex<TcpStream>,
    conn: &Mutex<RtdeConn>,
    even_if_not_due: bool,
) -> Result<bool, ()> {
    let (recipe, protocol) = {
        let c = lock(conn);
        match (&c.output, c.started) {
            (Some(r), true) if even_if_not_due || p.seq % r.divisor == 0 => (r.clone(), c.protocol),
            _ => return Ok(false),
        }
    };
    buf.clear();
    buf.extend_from_slice(&[0, 0, PackageType::DataPackage as u8]);
    // Protocol 1 data packages carry no recipe id.
    if protocol >= 2 {
        buf.push(recipe.id);
    }
    {
        let ctl = lock(&shared.ctl);
        for f in &recipe.fields {
            f.value(&p.snap, &ctl.inputs).encode(buf);
        }
    }
    if wire::patch_size(buf, 0).is_err() {
        log::error!("sim-ur5e RTDE: output recipe too large for one package");
        return Err(());
    }
    // Start/pause may have changed meanwhile: decide under the writer lock.
    let mut w = lock(writer);
    if !lock(conn).started || shared.link_faults.rtde_muted.load(Ordering::Relaxed) {
        return Ok(false);
    }
    w.write_all(buf).map(|()| true).map_err(|_| ())
}

fn rtde_requests(
    shared: &Shared,
    id: u64,
    mut stream: TcpStream,
    sync: &ReaderSync,
    writer: &Mutex<TcpStream>,
    conn: &Mutex<RtdeConn>,
) -> io::Result<()> {
    let mut buf = vec![0u8; 1 << 17];
    let (mut start, mut end) = (0usize, 0usize);
    loop {
        if start > 0 {
            buf.copy_within(start..end, 0);
            end -= start;
            start = 0;
        }
        if sync.wait_for_data(&stream)? == 0 {
            return Ok(());
        }
        let n = stream.read(&mut buf[end..])?;
        if n == 0 {
            return Ok(());
        }
        end += n;
        loop {
            let (pkg, used) = match wire::split_package(&buf[start..end]) {
                Ok(Some(x)) => x,
                Ok(None) => break,
                Err(e) => {
                    log::warn!("sim-ur5e RTDE connection {id}: {e}; closing");
                    return Ok(());
                }
            };
            let (ty, payload) = (pkg.type_byte, pkg.payload.to_vec());
            start += used;
            rtde_handle(shared, id, ty, &payload, writer, conn)?;
        }
    }
}

#[allow(clippy::too_many_lines, reason = "one arm per RTDE request type")]
fn rtde_handle(
    shared: &Shared,
    id: u64,
    ty: u8,
    payload: &[u8],
    writer: &Mutex<TcpStream>,
    conn: &Mutex<RtdeConn>,
) -> io::Result<()> {
    let Some(kind) = PackageType::from_byte(ty) else {
        log::warn!("sim-ur5e RTDE connection {id}: unknown package type {ty:#04x}; ignored");
        return Ok(());
    };
    match kind {
        PackageType::RequestProtocolVersion => {
            let version = match payload {
                [a, b] => u16::from_be_bytes([*a, *b]),
                _ => 0,
            };
            let ok = version == 1 || version == 2;
            if ok {
                lock(conn).protocol = version;
            }
            send_package(writer, kind, &[u8::from(ok)])
        }
        PackageType::GetUrcontrolVersion => {
            send_package(writer, kind, &shared.cfg.version.encode())
        }
        PackageType::SetupOutputs => {
            let protocol = lock(conn).protocol;
            let (frequency_hz, names) = if protocol >= 2 {
                if payload.len() < 8 {
                    log::warn!("sim-ur5e RTDE connection {id}: output setup without frequency");
                    return send_package(writer, kind, &[0]);
                }
                let mut f = [0u8; 8];
                f.copy_from_slice(&payload[..8]);
                (f64::from_be_bytes(f), &payload[8..])
            } else {
                (shared.cfg.rate_hz, payload)
            };
            let names = String::from_utf8_lossy(names);
            let mut words = Vec::new();
            let mut fields = Vec::new();
            {
                let ctl = lock(&shared.ctl);
                for name in wire::split_names(&names) {
                    match resolve_output(name, &ctl.inputs) {
                        Some(f) => {
                            words.push(SetupField::Type(f.ty).name());
                            fields.push(f);
                        }
                        None => words.push(SetupField::NotFound.name()),
                    }
                }
            }
            let valid = !fields.is_empty() && fields.len() == words.len();
            if !(frequency_hz > 0.0 && frequency_hz <= shared.cfg.rate_hz) {
                log::warn!(
                    "sim-ur5e RTDE connection {id}: output frequency {frequency_hz} Hz outside (0, {}]; clamped",
                    shared.cfg.rate_hz
                );
            }
            let f = if frequency_hz > 0.0 {
                frequency_hz.min(shared.cfg.rate_hz)
            } else {
                shared.cfg.rate_hz
            };
            let divisor = ((shared.cfg.rate_hz / f).round() as u64).max(1);
            // One output recipe per connection; id 1 as URCL's fake server does.
            let recipe_id = if valid { 1 } else { 0 };
            {
                let mut c = lock(conn);
                c.output = valid.then_some(OutputRecipe {
                    id: recipe_id,
                    divisor,
                    fields,
                });
            }
            let mut reply = Vec::new();
            if protocol >= 2 {
                reply.push(recipe_id);
            }
            reply.extend_from_slice(words.join(",").as_bytes());
            send_package(writer, kind, &reply)
        }
        PackageType::SetupInputs => {
            let names = String::from_utf8_lossy(payload);
            let mut words = Vec::new();
            let mut slots = Vec::new();
            let mut types = Vec::new();
            let mut ok = true;
            {
                let mut ctl = lock(&shared.ctl);
                let mut resolved = Vec::new();
                for name in wire::split_names(&names) {
                    match ctl.inputs.index_of(name) {
                        Some(i) => resolved.push(Some(i)),
                        None => {
                            resolved.push(None);
                            ok = false;
                        }
                    }
                }
                let known: Vec<usize> = resolved.iter().flatten().copied().collect();
                let in_use = if ok {
                    ctl.inputs.claim(&known, id)
                } else {
                    vec![false; known.len()]
                };
                ok &= !in_use.iter().any(|&b| b);
                let mut k = 0;
                for r in resolved {
                    match r {
                        None => words.push(SetupField::NotFound.name()),
                        Some(i) => {
                            let ty = ctl.inputs.slot(i).ty;
                            words.push(if in_use[k] {
                                SetupField::InUse.name()
                            } else {
                                ty.name()
                            });
                            slots.push(i);
                            types.push(ty);
                            k += 1;
                        }
                    }
                }
            }
            ok &= !slots.is_empty();
            let recipe_id = {
                let mut c = lock(conn);
                if ok {
                    // Numbered per connection from 1 in request order: ur_rtde hard-codes this.
                    let rid = c.next_input_id;
                    c.next_input_id = c.next_input_id.wrapping_add(1).max(1);
                    c.inputs.retain(|r| r.id != rid);
                    c.inputs.push(InputRecipe {
                        id: rid,
                        slots,
                        types,
                    });
                    rid
                } else {
                    0
                }
            };
            let mut reply = vec![recipe_id];
            reply.extend_from_slice(words.join(",").as_bytes());
            send_package(writer, kind, &reply)
        }
        PackageType::Start => {
            let mut w = lock(writer);
            let mut c = lock(conn);
            let ok = c.output.is_some();
            let mut buf = Vec::new();
            let _ = wire::push_package(&mut buf, kind, &[u8::from(ok)]);
            w.write_all(&buf)?;
            // Set after the reply is written, under the writer lock: no data before the reply.
            c.started = ok;
            drop((c, w));
            // Externally stepped, the next cycle may be far off (the world holds time until
            // every process has joined): send the current state now, as a real controller's
            // first package follows the start at once.
            if ok && shared.cfg.stepping == Stepping::External {
                let p = *lock(&shared.published);
                let mut buf = Vec::with_capacity(2048);
                if rtde_write_package(shared, &p, &mut buf, writer, conn, true).is_err() {
                    return Err(io::Error::other("writing the first data package"));
                }
            }
            Ok(())
        }
        PackageType::Pause => {
            let mut w = lock(writer);
            lock(conn).started = false;
            let mut buf = Vec::new();
            let _ = wire::push_package(&mut buf, kind, &[1]);
            w.write_all(&buf)
        }
        PackageType::DataPackage => {
            let Some((&rid, fields)) = payload.split_first() else {
                return Ok(());
            };
            let recipe = lock(conn).inputs.iter().find(|r| r.id == rid).cloned();
            let Some(recipe) = recipe else {
                log::warn!(
                    "sim-ur5e RTDE connection {id}: data for unknown input recipe {rid}; ignored"
                );
                return Ok(());
            };
            let mut values = vec![RtdeValue::Bool(false); recipe.types.len()];
            if let Err(e) = wire::decode_fields(&recipe.types, fields, &mut values) {
                // Logged and ignored, never a dropped connection (reference §2.4).
                log::warn!("sim-ur5e RTDE connection {id}: input recipe {rid}: {e}; ignored");
                let msg = TextMessage {
                    message: format!("input package for recipe {rid} does not match the recipe"),
                    source: "RTDE".into(),
                    level: TextLevel::Warning,
                };
                let mut p = Vec::new();
                msg.encode(&mut p);
                return send_package(writer, PackageType::TextMessage, &p);
            }
            let mut ctl = lock(&shared.ctl);
            let now = ctl.robot.time_s();
            for (&slot, value) in recipe.slots.iter().zip(values) {
                ctl.inputs.write(slot, value, now);
            }
            ctl.apply_io();
            Ok(())
        }
        PackageType::TextMessage => {
            match TextMessage::decode(payload) {
                Ok(m) => log::info!("sim-ur5e RTDE client {id} [{}]: {}", m.source, m.message),
                Err(e) => log::warn!("sim-ur5e RTDE client {id}: bad text message: {e}"),
            }
            Ok(())
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Dashboard (29999)

fn dashboard_connection(shared: &Arc<Shared>, stream: TcpStream) -> io::Result<()> {
    let mut writer = stream.try_clone()?;
    writer.write_all(b"Connected: Universal Robots Dashboard Server\n")?;
    let mut reader = BufReader::new(stream);
    let mut line = String::new();
    let mut loaded: Option<String> = None;
    loop {
        line.clear();
        // Bounded: a client cannot make the controller buffer without end.
        if (&mut reader).take(4096).read_line(&mut line)? == 0 {
            return Ok(());
        }
        let command = line.trim_end_matches(['\n', '\r']).trim();
        let reply = dashboard_reply(shared, command, &mut loaded);
        let delay_ms = shared
            .link_faults
            .dashboard_delay_ms
            .load(Ordering::Relaxed);
        if delay_ms > 0 {
            std::thread::sleep(Duration::from_millis(delay_ms));
        }
        writer.write_all(reply.as_bytes())?;
        writer.write_all(b"\n")?;
        if command == "quit" {
            let _ = writer.shutdown(Shutdown::Both);
            return Ok(());
        }
    }
}

#[allow(clippy::too_many_lines, reason = "one arm per dashboard command")]
fn dashboard_reply(shared: &Arc<Shared>, command: &str, loaded: &mut Option<String>) -> String {
    let cfg = &shared.cfg;
    let mut ctl = lock(&shared.ctl);
    let robot = &mut ctl.robot;
    let program_name = || -> String { loaded.clone().unwrap_or_else(|| "<unnamed>".into()) };
    if let Some(file) = command.strip_prefix("load installation ") {
        return format!("Loading installation: {file}");
    }
    if let Some(file) = command.strip_prefix("load ") {
        return if cfg.programs.iter().any(|p| p == file) {
            *loaded = Some(file.to_string());
            format!("Loading program: {file}")
        } else {
            format!("File not found: {file}")
        };
    }
    if command.starts_with("popup ") {
        return "showing popup".into();
    }
    if let Some(text) = command.strip_prefix("addToLog ") {
        log::info!("sim-ur5e dashboard log: {text}");
        return "Added log message".into();
    }
    if let Some(mode) = command.strip_prefix("set operational mode ") {
        return format!("Operational mode {mode} is set");
    }
    if let Some(role) = command.strip_prefix("setUserRole ") {
        return format!("Setting user role: {role}");
    }
    match command {
        "power on" => {
            robot.power_on();
            "Powering on".into()
        }
        "power off" => {
            robot.power_off();
            "Powering off".into()
        }
        "brake release" => {
            robot.brake_release();
            "Brake releasing".into()
        }
        "play"
            if loaded.is_some()
                && cfg.urcap_script_sender.is_some()
                && robot.runtime_state() == crate::robot::runtime_state::STOPPED =>
        {
            // The loaded program is the External Control URCap's: it asks the script sender.
            if let Some(addr) = cfg.urcap_script_sender {
                request_urcap_program(shared, addr);
            }
            "Starting program".into()
        }
        "play" => {
            if robot.play() {
                "Starting program".into()
            } else {
                "Failed to execute: play".into()
            }
        }
        "stop" => {
            robot.dashboard_stop();
            "Stopped".into()
        }
        "pause" => {
            if robot.pause() {
                "Pausing program".into()
            } else {
                "Failed to execute: pause".into()
            }
        }
        "unlock protective stop" => {
            robot.unlock_protective_stop();
            "Protective stop releasing".into()
        }
        "close popup" => "closing popup".into(),
        "close safety popup" => "closing safety popup".into(),
        "restart safety" => "Restarting safety".into(),
        "robotmode" => format!(
            "Robotmode: {}",
            ur5e::dashboard::RobotMode::from_code(robot.robot_mode())
                .map_or("NO_CONTROLLER", |m| m.name())
        ),
        "safetystatus" | "safetymode" => {
            let name = ur5e::dashboard::SafetyMode::from_code(robot.safety_mode())
                .map_or("UNDEFINED_SAFETY_MODE", |m| m.name());
            if command == "safetystatus" {
                format!("Safetystatus: {name}")
            } else {
                format!("Safetymode: {name}")
            }
        }
        "programState" => {
            let name = robot
                .program_name()
                .map(str::to_string)
                .unwrap_or_else(program_name);
            match robot.runtime_state() {
                2 => format!("PLAYING {name}"),
                4 => format!("PAUSED {name}"),
                _ => format!("STOPPED {name}"),
            }
        }
        "running" => format!("Program running: {}", robot.runtime_state() == 2),
        "get loaded program" => match loaded {
            Some(p) => format!("Loaded program: {p}"),
            None => "No program loaded".into(),
        },
        "isProgramSaved" => format!("true {}", program_name()),
        "PolyscopeVersion" => format!("URSoftware {} (Jan 01 2025)", cfg.version),
        "version" => cfg.version.to_string(),
        "get serial number" => cfg.serial_number.clone(),
        "get robot model" => "UR5".into(),
        "is in remote control" => cfg.remote_control.to_string(),
        "get operational mode" => "NONE".into(),
        "clear operational mode" => {
            "No longer controlling the operational mode. Current operational mode: 'NONE'.".into()
        }
        "getUserRole" => "PROGRAMMER".into(),
        "quit" => "Disconnected".into(),
        "shutdown" => {
            robot.power_off();
            "Shutting down".into()
        }
        other => format!("could not understand: '{other}'"),
    }
}

// ---------------------------------------------------------------------------------------------
// Primary / secondary / real-time (30001 / 30002 / 30003)

fn script_connection(
    shared: &Arc<Shared>,
    id: u64,
    kind: PortKind,
    stream: TcpStream,
) -> io::Result<()> {
    let writer = stream.try_clone()?;
    let done = Arc::new(AtomicBool::new(false));
    let streamer = {
        let (shared, done) = (Arc::clone(shared), Arc::clone(&done));
        std::thread::Builder::new()
            .name(format!("sim-ur5e-{kind:?}-out"))
            .spawn(move || state_stream(&shared, kind, writer, &done))?
    };
    let sync = match shared.add_reader(id, &stream) {
        Ok(s) => s,
        Err(e) => {
            done.store(true, Ordering::Release);
            shared.tick.notify_all();
            let _ = streamer.join();
            return Err(e);
        }
    };
    let result = script_reader(shared, kind, stream, &sync);
    shared.remove_reader(id);
    done.store(true, Ordering::Release);
    shared.tick.notify_all();
    let _ = streamer.join();
    result
}

/// Streams robot state: 10 Hz packages on 30001/30002 (after the version message), one
/// real-time packet per control cycle on 30003.
fn state_stream(shared: &Shared, kind: PortKind, mut w: TcpStream, done: &AtomicBool) {
    let mut buf = Vec::with_capacity(2048);
    if kind != PortKind::Realtime {
        primary::version_message(&shared.cfg.version, &mut buf);
        if w.write_all(&buf).is_err() {
            return;
        }
    }
    let every = if kind == PortKind::Realtime {
        1
    } else {
        ((shared.cfg.rate_hz / 10.0).round() as u64).max(1)
    };
    let mut seen = lock(&shared.published).seq;
    while !done.load(Ordering::Acquire) && !shared.stopping() {
        let Some(p) = shared.wait_newer(seen, Duration::from_millis(100)) else {
            continue;
        };
        seen = p.seq;
        if p.seq % every != 0 {
            continue;
        }
        if kind == PortKind::Realtime {
            primary::realtime(&p.snap, &mut buf);
        } else {
            primary::robot_state(&p.snap, &mut buf);
        }
        if w.write_all(&buf).is_err() {
            return;
        }
    }
}

/// Collects script text; runs each complete program (a `def`/`sec` block up to its `end`, or
/// a single bare line).
fn script_reader(
    shared: &Arc<Shared>,
    kind: PortKind,
    mut stream: TcpStream,
    sync: &ReaderSync,
) -> io::Result<()> {
    let mut pending = String::new();
    let mut chunk = vec![0u8; 64 * 1024];
    loop {
        if sync.wait_for_data(&stream)? == 0 {
            return Ok(());
        }
        let n = stream.read(&mut chunk)?;
        if n == 0 {
            return Ok(());
        }
        pending.push_str(&String::from_utf8_lossy(&chunk[..n]));
        while let Some(program) = take_program(&mut pending) {
            run_script(shared, kind, &program);
        }
        if pending.len() > 1 << 20 {
            log::warn!("sim-ur5e {kind:?}: over 1 MiB of unterminated script text; discarded");
            pending.clear();
        }
    }
}

/// Removes the first complete program from `pending`.
fn take_program(pending: &mut String) -> Option<String> {
    let trimmed_start = pending.len() - pending.trim_start().len();
    pending.drain(..trimmed_start);
    if pending.is_empty() {
        return None;
    }
    if pending.starts_with("def ") || pending.starts_with("sec ") {
        let mut offset = 0;
        for line in pending.split_inclusive('\n') {
            offset += line.len();
            if line.ends_with('\n')
                && line.trim_end() == "end"
                && !line.starts_with(char::is_whitespace)
            {
                let program: String = pending.drain(..offset).collect();
                return Some(program);
            }
        }
        None
    } else {
        let end = pending.find('\n')? + 1;
        Some(pending.drain(..end).collect())
    }
}

fn run_script(shared: &Arc<Shared>, kind: PortKind, text: &str) {
    let command = text.trim();
    if is_external_control(text) {
        match parse_external_control(text) {
            Ok(script) => start_external_control(shared, script),
            Err(e) => log::error!("sim-ur5e {kind:?}: External Control program rejected: {e}"),
        }
        return;
    }
    let mut ctl = lock(&shared.ctl);
    // Primary-port commands that are not URScript (reference §3.1).
    if kind == PortKind::Primary {
        match command {
            "power on" => return ctl.robot.power_on(),
            "power off" => return ctl.robot.power_off(),
            "set robotmode run" => return ctl.robot.brake_release(),
            "set unlock protective stop" => return ctl.robot.unlock_protective_stop(),
            "stop program" => return ctl.robot.stop_program("primary stop program"),
            _ => {}
        }
    }
    if is_rtde_control(text) {
        match parse_rtde_control(text) {
            Ok(script) => {
                log::info!(
                    "sim-ur5e {kind:?}: ur_rtde control script (register offsets {}/{}, path of {} steps), served natively",
                    script.int_offset,
                    script.float_offset,
                    script.path.len()
                );
                let Controller { robot, inputs } = &mut *ctl;
                robot.load_rtde_control(script, inputs);
            }
            Err(e) => log::error!("sim-ur5e {kind:?}: ur_rtde control script rejected: {e}"),
        }
        return;
    }
    match parse_program(text) {
        Ok(program) => {
            log::info!(
                "sim-ur5e {kind:?}: program {} ({} statements)",
                program.name,
                program.statements.len()
            );
            ctl.robot.load_program(program);
        }
        Err(e) => log::error!("sim-ur5e {kind:?}: script rejected: {e}"),
    }
}

// ---------------------------------------------------------------------------------------------
// Gripper (63352)

fn gripper_connection(shared: &Shared, stream: TcpStream) -> io::Result<()> {
    let mut writer = stream.try_clone()?;
    let mut reader = BufReader::new(stream);
    let mut line = String::new();
    loop {
        line.clear();
        // Bounded: a client cannot make the controller buffer without end.
        if (&mut reader).take(4096).read_line(&mut line)? == 0 {
            return Ok(());
        }
        let reply = lock(&shared.ctl).robot.gripper.handle(line.trim());
        if shared.link_faults.gripper_muted.load(Ordering::Relaxed) {
            continue; // read, never answered
        }
        writer.write_all(reply.as_bytes())?;
        writer.write_all(b"\n")?;
    }
}

// ---------------------------------------------------------------------------------------------
// External Control (URCL): the robot side of its reverse, trajectory and script command sockets

/// The External Control URCap's program node: asks the script sender for the program
/// (`request_program\n`), reads it until the sender closes or falls silent, and runs it.
fn request_urcap_program(shared: &Arc<Shared>, addr: SocketAddr) {
    let shared = Arc::clone(shared);
    let spawned = std::thread::Builder::new()
        .name("sim-ur5e-urcap".into())
        .spawn(move || {
            let fetch = || -> io::Result<String> {
                let mut s = TcpStream::connect_timeout(&addr, Duration::from_secs(2))?;
                s.write_all(b"request_program\n")?;
                s.set_read_timeout(Some(Duration::from_millis(500)))?;
                let mut text = Vec::new();
                let mut chunk = [0u8; 16 * 1024];
                loop {
                    match s.read(&mut chunk) {
                        Ok(0) => break,
                        Ok(n) => {
                            text.extend_from_slice(&chunk[..n]);
                            if text.len() > 1 << 20 {
                                return Err(io::Error::other("program over 1 MiB"));
                            }
                        }
                        Err(e)
                            if matches!(
                                e.kind(),
                                io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                            ) && !text.is_empty() =>
                        {
                            break;
                        }
                        Err(e) => return Err(e),
                    }
                }
                Ok(String::from_utf8_lossy(&text).into_owned())
            };
            match fetch() {
                Ok(text) if is_external_control(&text) => match parse_external_control(&text) {
                    Ok(script) => start_external_control(&shared, script),
                    Err(e) => log::error!("sim-ur5e URCap: program from {addr} rejected: {e}"),
                },
                Ok(_) => log::error!(
                    "sim-ur5e URCap: the program from {addr} is not an External Control program"
                ),
                Err(e) => log::error!("sim-ur5e URCap: requesting the program from {addr}: {e}"),
            }
        });
    if let Err(e) = spawned {
        log::error!("sim-ur5e URCap: cannot spawn: {e}");
    }
}

/// Connects the program's three sockets (as `connect_socket_with_retry`: 5 tries, 0.2 s apart)
/// and serves the session on its own threads.
fn start_external_control(shared: &Arc<Shared>, script: ExternalControlScript) {
    let shared = Arc::clone(shared);
    let spawned = std::thread::Builder::new()
        .name("sim-ur5e-extctl".into())
        .spawn(move || external_control_session(&shared, &script));
    if let Err(e) = spawned {
        log::error!("sim-ur5e External Control: cannot spawn: {e}");
    }
}

fn external_control_session(shared: &Arc<Shared>, script: &ExternalControlScript) {
    let connect = |addr: SocketAddr, name: &str| -> Option<TcpStream> {
        for attempt in 1..=5 {
            match TcpStream::connect_timeout(&addr, Duration::from_secs(1)) {
                Ok(s) => {
                    let _ = s.set_nodelay(true);
                    return Some(s);
                }
                Err(e) if attempt == 5 => {
                    log::error!("sim-ur5e External Control: {name} at {addr}: {e}");
                }
                Err(_) => std::thread::sleep(Duration::from_millis(200)),
            }
        }
        None
    };
    let Some(trajectory) = connect(script.trajectory, "trajectory_socket") else {
        return;
    };
    let Some(command) = connect(script.script_command, "script_command_socket") else {
        return;
    };
    let Some(reverse) = connect(script.reverse, "reverse_socket") else {
        return;
    };
    let sockets = [&trajectory, &command, &reverse];
    let close = || {
        for s in sockets {
            let _ = s.shutdown(Shutdown::Both);
        }
    };
    // Registered before the session starts: a step never runs ahead of a message that was
    // sent before it (lock-step), even before the reader threads are scheduled.
    let mut registered = Vec::new();
    for s in sockets {
        let id = shared.next_conn.fetch_add(1, Ordering::Relaxed);
        match (s.try_clone(), shared.add_reader(id, s)) {
            (Ok(stream), Ok(sync)) => registered.push((id, stream, sync)),
            _ => {
                for (id, _, _) in &registered {
                    shared.remove_reader(*id);
                }
                shared.remove_reader(id);
                close();
                return;
            }
        }
    }
    let session = lock(&shared.ctl).robot.load_external_control(script);
    let Some(session) = session else {
        for (id, _, _) in &registered {
            shared.remove_reader(*id);
        }
        close();
        return;
    };
    let mut registered = registered.into_iter();
    let mut next = || registered.next();
    log::info!(
        "sim-ur5e External Control: session {session} connected to {}",
        script.reverse
    );
    // Same order as `sockets`: trajectory, script command, reverse.
    let readers = [
        spawn_ext_reader::<TRAJECTORY_POINT_INTS>(shared, session, next(), |r, s, m| {
            r.external_trajectory_point(s, m)
        }),
        spawn_ext_reader::<SCRIPT_COMMAND_INTS>(shared, session, next(), |r, s, m| {
            r.external_script_command(s, m)
        }),
        spawn_ext_reader::<REVERSE_MESSAGE_INTS>(shared, session, next(), |r, s, m| {
            r.external_reverse(s, m)
        }),
    ];
    // Results go out after the cycle that produced them.
    let mut writer = &trajectory;
    let mut seen = lock(&shared.published).seq;
    let mut out = Vec::with_capacity(16);
    while !shared.stopping() {
        if let Some(p) = shared.wait_newer(seen, Duration::from_millis(100)) {
            seen = p.seq;
        }
        let Some(results) = lock(&shared.ctl).robot.external_take_results(session) else {
            break;
        };
        if results.is_empty() {
            continue;
        }
        out.clear();
        encode_ints(&results, &mut out);
        if writer.write_all(&out).is_err() {
            break;
        }
    }
    close();
    for r in readers.into_iter().flatten() {
        let _ = r.join();
    }
    log::info!("sim-ur5e External Control: session {session} closed");
}

/// A reader thread for one External Control socket: fixed-size messages of `N` big-endian
/// `i32`, each applied to the model as it arrives (registered for lock-step like every input).
fn spawn_ext_reader<const N: usize>(
    shared: &Arc<Shared>,
    session: u64,
    registered: Option<(u64, TcpStream, Arc<ReaderSync>)>,
    apply: fn(&mut crate::robot::RobotModel, u64, &[i32; N]),
) -> Option<JoinHandle<()>> {
    let (id, mut stream, sync) = registered?;
    let shared = Arc::clone(shared);
    let for_thread = Arc::clone(&shared);
    let spawned = std::thread::Builder::new()
        .name("sim-ur5e-extctl-in".into())
        .spawn(move || {
            let shared = for_thread;
            let mut pending = Vec::with_capacity(8 * N * 4);
            let mut chunk = [0u8; 4096];
            let mut ints = [0i32; N];
            loop {
                match sync.wait_for_data(&stream) {
                    Ok(0) | Err(_) => break,
                    Ok(_) => {}
                }
                let n = match stream.read(&mut chunk) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => n,
                };
                pending.extend_from_slice(&chunk[..n]);
                let size = 4 * N;
                let mut used = 0;
                while pending.len() - used >= size {
                    decode_ints(&pending[used..used + size], &mut ints);
                    used += size;
                    let mut ctl = lock(&shared.ctl);
                    apply(&mut ctl.robot, session, &ints);
                }
                pending.drain(..used);
            }
            shared.remove_reader(id);
        });
    match spawned {
        Ok(h) => Some(h),
        Err(e) => {
            shared.remove_reader(id);
            log::error!("sim-ur5e External Control: cannot spawn a reader: {e}");
            None
        }
    }
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
