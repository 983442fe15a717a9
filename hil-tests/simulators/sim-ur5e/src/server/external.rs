//! External Control (URCL): the robot side of its reverse, trajectory and script command sockets.

use super::*;

/// The External Control URCap's program node: asks the script sender for the program
/// (`request_program\n`), reads it until the sender closes or falls silent, and runs it.
pub(super) fn request_urcap_program(shared: &Arc<Shared>, addr: SocketAddr) {
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
pub(super) fn start_external_control(shared: &Arc<Shared>, script: ExternalControlScript) {
    let shared = Arc::clone(shared);
    let spawned = std::thread::Builder::new()
        .name("sim-ur5e-extctl".into())
        .spawn(move || external_control_session(&shared, &script));
    if let Err(e) = spawned {
        log::error!("sim-ur5e External Control: cannot spawn: {e}");
    }
}

pub(super) fn external_control_session(shared: &Arc<Shared>, script: &ExternalControlScript) {
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
pub(super) fn spawn_ext_reader<const N: usize>(
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
