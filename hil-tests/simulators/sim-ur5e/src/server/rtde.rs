//! RTDE (port 30004): the handshake, recipes, the output stream and the inputs.

use super::*;

#[derive(Debug, Default)]
pub(super) struct RtdeConn {
    protocol: u16,
    started: bool,
    output: Option<OutputRecipe>,
    inputs: Vec<InputRecipe>,
    next_input_id: u8,
    closed: bool,
}

#[derive(Debug, Clone)]
pub(super) struct OutputRecipe {
    id: u8,
    divisor: u64,
    fields: Vec<OutputField>,
}

#[derive(Debug, Clone)]
pub(super) struct InputRecipe {
    id: u8,
    slots: Vec<usize>,
    types: Vec<RtdeType>,
}

pub(super) fn send_package(
    w: &Mutex<TcpStream>,
    ty: PackageType,
    payload: &[u8],
) -> io::Result<()> {
    let mut buf = Vec::with_capacity(payload.len() + wire::HEADER_LEN);
    wire::push_package(&mut buf, ty, payload)
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
    lock(w).write_all(&buf)
}

pub(super) fn rtde_connection(shared: &Arc<Shared>, id: u64, stream: TcpStream) -> io::Result<()> {
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
pub(super) fn rtde_stream(
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
pub(super) fn rtde_write_package(
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

pub(super) fn rtde_requests(
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
pub(super) fn rtde_handle(
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
