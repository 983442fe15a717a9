//! The primary, secondary and real-time interfaces (30001 / 30002 / 30003): state streams and URScript programs.

use super::*;

pub(super) fn script_connection(
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
pub(super) fn state_stream(shared: &Shared, kind: PortKind, mut w: TcpStream, done: &AtomicBool) {
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
pub(super) fn script_reader(
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
pub(super) fn take_program(pending: &mut String) -> Option<String> {
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

pub(super) fn run_script(shared: &Arc<Shared>, kind: PortKind, text: &str) {
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
