//! The RTDE client against a scripted controller written byte by byte here (independent of
//! the simulator's encoder, so a shared codec bug cannot hide).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

use ur5e::rtde::wire::ValueDecodeError;
use ur5e::rtde::{
    DataPackage, RtdeClient, RtdeLinkError, RtdeMalformed, RtdeReceiveError, RtdeReconnectError,
    RtdeReconnectPolicy, RtdeSetupError, RtdeState, RtdeTimeouts, RtdeType, RtdeValue,
};

fn pkg(ty: u8, payload: &[u8]) -> Vec<u8> {
    let mut v = ((payload.len() + 3) as u16).to_be_bytes().to_vec();
    v.push(ty);
    v.extend_from_slice(payload);
    v
}

/// Reads one request package and returns (type, payload).
fn read_request(s: &mut TcpStream) -> (u8, Vec<u8>) {
    let mut h = [0u8; 3];
    s.read_exact(&mut h).unwrap();
    let len = u16::from_be_bytes([h[0], h[1]]) as usize - 3;
    let mut p = vec![0u8; len];
    s.read_exact(&mut p).unwrap();
    (h[2], p)
}

fn data(recipe: u8, t: f64, q0: f64, mode: i32) -> Vec<u8> {
    let mut p = vec![recipe];
    p.extend_from_slice(&t.to_be_bytes());
    for i in 0..6 {
        p.extend_from_slice(&(q0 + i as f64).to_be_bytes());
    }
    p.extend_from_slice(&mode.to_be_bytes());
    pkg(b'U', &p)
}

fn text(msg: &str) -> Vec<u8> {
    let mut p = vec![msg.len() as u8];
    p.extend_from_slice(msg.as_bytes());
    p.push(4);
    p.extend_from_slice(b"RTDE");
    p.push(2);
    pkg(b'M', &p)
}

/// Serves the handshake, then runs `after_start` on the socket.
fn fake_controller(
    after_start: impl FnOnce(&mut TcpStream) + Send + 'static,
) -> (u16, thread::JoinHandle<()>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let handle = thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        let _ = serve_handshake(&mut s);
        after_start(&mut s);
    });
    (port, handle)
}

/// Answers requests (`V`, `v`, `O`, `I`, `S`) until the stream is started; returns the
/// request types in the order they came.
fn serve_handshake(s: &mut TcpStream) -> Vec<u8> {
    let mut seen = Vec::new();
    loop {
        let (ty, payload) = read_request(s);
        seen.push(ty);
        match ty {
            b'V' => {
                assert_eq!(payload, [0, 2], "client asks for protocol 2");
                s.write_all(&pkg(b'V', &[1])).unwrap();
            }
            b'v' => {
                let mut p = Vec::new();
                for v in [5u32, 21, 0, 42] {
                    p.extend_from_slice(&v.to_be_bytes());
                }
                // A text message before the reply must be logged, not taken as the reply.
                s.write_all(&text("hello")).unwrap();
                s.write_all(&pkg(b'v', &p)).unwrap();
            }
            b'O' => {
                assert_eq!(&payload[..8], &500.0f64.to_be_bytes());
                let names = String::from_utf8(payload[8..].to_vec()).unwrap();
                let reply = if names == "timestamp,actual_q,robot_mode" {
                    b"\x07DOUBLE,VECTOR6D,INT32".to_vec()
                } else {
                    let n = names.split(',').count();
                    let mut r = vec![7u8];
                    r.extend_from_slice(vec!["NOT_FOUND"; n].join(",").as_bytes());
                    r
                };
                s.write_all(&pkg(b'O', &reply)).unwrap();
            }
            b'I' => {
                let reply: &[u8] = if payload == b"input_int_register_0" {
                    b"\x01INT32"
                } else {
                    b"\x01IN_USE"
                };
                s.write_all(&pkg(b'I', reply)).unwrap();
            }
            b'S' => {
                s.write_all(&pkg(b'S', &[1])).unwrap();
                return seen;
            }
            other => panic!("unexpected request {other}"),
        }
    }
}

fn connect(port: u16) -> RtdeClient {
    let mut c = RtdeClient::connect(("127.0.0.1", port), RtdeTimeouts::default()).unwrap();
    let v = c.controller_version().unwrap();
    assert_eq!((v.major, v.minor, v.build), (5, 21, 42));
    assert_eq!(c.text_messages(), 1);
    let r = c
        .setup_outputs(&["timestamp", "actual_q", "robot_mode"], 500.0)
        .unwrap();
    assert_eq!(r.id, 7);
    assert_eq!(
        r.types,
        [RtdeType::Double, RtdeType::Vector6d, RtdeType::Int32]
    );
    c
}

#[test]
fn newest_package_wins_and_values_decode_by_the_returned_types() {
    let (port, server) = fake_controller(|s| {
        let mut burst = Vec::new();
        for k in 0..5 {
            burst.extend(data(7, 0.002 * k as f64, k as f64, 7));
        }
        burst.extend(text("interleaved warning"));
        s.write_all(&burst).unwrap();
        thread::sleep(Duration::from_millis(300));
    });
    let mut c = connect(port);
    c.start().unwrap();
    let mut pkg = DataPackage::for_recipe(c.output_recipe().unwrap());
    thread::sleep(Duration::from_millis(100));
    c.receive_latest(&mut pkg, Duration::from_secs(1)).unwrap();
    assert_eq!(pkg.values[0], RtdeValue::Double(0.008));
    assert_eq!(
        pkg.values[1],
        RtdeValue::Vector6d([4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
    );
    assert_eq!(pkg.values[2], RtdeValue::Int32(7));
    assert_eq!(pkg.skipped, 4);
    assert_eq!(pkg.sequence, 5);
    assert_eq!(c.text_messages(), 2);
    server.join().unwrap();
}

#[test]
fn not_found_and_in_use_are_typed_setup_errors() {
    let (port, server) = fake_controller(|_| {});
    let mut c = connect(port);
    match c.setup_outputs(&["actual_q", "bogus"], 500.0) {
        Err(RtdeSetupError::NotFound { names }) => assert_eq!(names, ["actual_q", "bogus"]),
        other => panic!("{other:?}"),
    }
    match c.setup_inputs(&["input_int_register_24"]) {
        Err(RtdeSetupError::InUse { names }) => assert_eq!(names, ["input_int_register_24"]),
        other => panic!("{other:?}"),
    }
    // The earlier valid recipe is still in place and the stream can start.
    c.setup_outputs(&["timestamp", "actual_q", "robot_mode"], 500.0)
        .unwrap();
    c.start().unwrap();
    drop(c);
    server.join().unwrap();
}

/// Waits for the test's go, then writes `bytes` in one write.
fn send_on_go(s: &mut TcpStream, go: &mpsc::Receiver<()>, bytes: &[u8]) {
    go.recv().unwrap();
    s.write_all(bytes).unwrap();
}

#[test]
fn malformed_packages_are_consumed_counted_and_named_and_later_data_still_arrives() {
    // Recipe 7 is 8 + 48 + 4 bytes of fields.
    let mut short = vec![7u8];
    short.extend_from_slice(&[0u8; 56]);
    let short = pkg(b'U', &short);
    let mut other_recipe = data(7, 0.0, 0.0, 7);
    other_recipe[3] = 9;
    let unknown = pkg(b'X', &[1, 2, 3]);
    // A size field below the 3-byte header: the stream has lost its framing.
    let bad_size = [0x00u8, 0x01, 0xAA];
    let groups: Vec<Vec<u8>> = vec![
        [short.clone(), data(7, 1.0, 0.0, 7)].concat(),
        [unknown, data(7, 2.0, 0.0, 7)].concat(),
        [other_recipe, data(7, 3.0, 0.0, 7)].concat(),
        [bad_size.to_vec(), data(7, 4.0, 0.0, 7)].concat(),
        short,
        data(7, 5.0, 0.0, 7),
    ];
    let (go_tx, go) = mpsc::channel();
    let (port, server) = fake_controller(move |s| {
        for g in &groups {
            send_on_go(s, &go, g);
        }
        // Hold the socket until the client is done.
        let _ = go.recv();
    });
    let mut c = connect(port);
    c.start().unwrap();
    let mut pkg = DataPackage::for_recipe(c.output_recipe().unwrap());
    let mut expect = |t: f64, count: u64, what: &dyn Fn(&RtdeMalformed) -> bool| {
        go_tx.send(()).unwrap();
        c.receive_latest(&mut pkg, Duration::from_secs(2))
            .unwrap_or_else(|e| panic!("package {t}: {e}"));
        assert_eq!(pkg.values[0], RtdeValue::Double(t));
        assert_eq!(
            pkg.skipped, 0,
            "malformed packages are not counted as skipped data"
        );
        assert_eq!(c.malformed_packages(), count);
        let last = c.last_malformed().unwrap();
        assert!(what(&last), "package {t}: {last:?}");
        // The report names what was wrong.
        assert!(!last.to_string().is_empty());
    };
    expect(1.0, 1, &|m| {
        matches!(
            m,
            RtdeMalformed::DataMismatch {
                recipe_id: 7,
                source: ValueDecodeError::Truncated { index: 2, .. }
            }
        )
    });
    expect(2.0, 2, &|m| {
        matches!(
            m,
            RtdeMalformed::UnknownType {
                type_byte: b'X',
                len: 3
            }
        )
    });
    expect(3.0, 3, &|m| {
        matches!(
            m,
            RtdeMalformed::WrongRecipe {
                got: 9,
                expected: 7
            }
        )
    });
    expect(4.0, 4, &|m| {
        matches!(
            m,
            RtdeMalformed::BadSize {
                size: 1,
                skipped: 3
            }
        )
    });
    // Only a malformed package before the deadline: an error that says so, not a timeout.
    go_tx.send(()).unwrap();
    match c.receive_latest(&mut pkg, Duration::from_millis(300)) {
        Err(RtdeReceiveError::Malformed { count: 1, last }) => {
            assert!(
                matches!(last, RtdeMalformed::DataMismatch { .. }),
                "{last:?}"
            )
        }
        other => panic!("{other:?}"),
    }
    // The failed decode left the previous values alone.
    assert_eq!(pkg.values[0], RtdeValue::Double(4.0));
    go_tx.send(()).unwrap();
    c.receive_latest(&mut pkg, Duration::from_secs(2)).unwrap();
    assert_eq!(pkg.values[0], RtdeValue::Double(5.0));
    assert_eq!(c.malformed_packages(), 5);
    go_tx.send(()).unwrap();
    server.join().unwrap();
}

/// Writes data packages, each after a few text messages (more work per byte for the client
/// than for us), as fast as the socket takes them, for at most `limit` or until the client
/// goes away.
fn flood(s: &mut TcpStream, limit: Duration) {
    let mut burst = Vec::new();
    for k in 0..2000 {
        for _ in 0..4 {
            burst.extend(text("x"));
        }
        burst.extend(data(7, k as f64, 0.0, 7));
    }
    let start = Instant::now();
    while start.elapsed() < limit {
        if s.write_all(&burst).is_err() {
            return;
        }
    }
}

#[test]
fn a_flooding_controller_cannot_hold_a_receive_past_its_deadline() {
    // The flood lasts far longer than any receive's deadline; a receive that only returns when
    // the socket runs dry returns after it (or sees the close), which the bounds below catch.
    let flood_for = Duration::from_secs(6);
    let (port, server) = fake_controller(move |s| flood(s, flood_for));
    let mut c = connect(port);
    c.start().unwrap();
    let mut pkg = DataPackage::for_recipe(c.output_recipe().unwrap());
    // Let the flood fill the socket buffers first.
    thread::sleep(Duration::from_millis(200));
    let t0 = Instant::now();
    c.receive_latest(&mut pkg, Duration::from_millis(100))
        .unwrap();
    let latest_took = t0.elapsed();
    let t0 = Instant::now();
    assert!(
        c.receive_newest(&mut pkg, Duration::from_millis(100))
            .unwrap()
    );
    let newest_took = t0.elapsed();
    // Generous bounds (deadlines of 100 ms): a loaded machine must not fail this, a receive
    // that runs until the 6 s flood ends must.
    assert!(latest_took < Duration::from_secs(2), "{latest_took:?}");
    assert!(newest_took < Duration::from_secs(2), "{newest_took:?}");
    assert!(pkg.skipped > 0);
    drop(c);
    server.join().unwrap();
}

#[test]
fn reconnect_resends_the_recipes_and_start_after_a_lost_link() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let server = thread::spawn(move || {
        // First connection: handshake, one package, then the controller goes away.
        let (mut s, _) = listener.accept().unwrap();
        let first = serve_handshake(&mut s);
        s.write_all(&data(7, 1.0, 0.0, 7)).unwrap();
        thread::sleep(Duration::from_millis(50));
        drop(s);
        // Second: accepted and dropped at once (a controller still booting): one failed attempt.
        let (s, _) = listener.accept().unwrap();
        drop(s);
        // Third: the setup is replayed in the original order and the stream restarts.
        let (mut s, _) = listener.accept().unwrap();
        let again = serve_handshake(&mut s);
        s.write_all(&data(7, 2.0, 0.0, 7)).unwrap();
        thread::sleep(Duration::from_millis(200));
        (first, again)
    });
    let mut c = RtdeClient::connect(("127.0.0.1", port), RtdeTimeouts::default()).unwrap();
    c.setup_outputs(&["timestamp", "actual_q", "robot_mode"], 500.0)
        .unwrap();
    let input = c.setup_inputs(&["input_int_register_0"]).unwrap();
    c.start().unwrap();
    let mut pkg = DataPackage::for_recipe(c.output_recipe().unwrap());
    c.receive_latest(&mut pkg, Duration::from_secs(2)).unwrap();
    assert_eq!(pkg.values[0], RtdeValue::Double(1.0));
    assert!(matches!(
        c.receive_latest(&mut pkg, Duration::from_secs(2)),
        Err(RtdeReceiveError::Link(RtdeLinkError::Closed { .. }))
    ));
    let policy = RtdeReconnectPolicy {
        attempts: 3,
        first_backoff: Duration::from_millis(10),
        max_backoff: Duration::from_millis(40),
    };
    c.reconnect(&policy).unwrap();
    assert_eq!(c.state(), RtdeState::Started);
    assert_eq!(c.reconnects(), 1);
    c.receive_latest(&mut pkg, Duration::from_secs(2)).unwrap();
    assert_eq!(pkg.values[0], RtdeValue::Double(2.0));
    // The input recipe the caller holds is still valid on the new connection.
    c.send_inputs(&input, &[RtdeValue::Int32(5)]).unwrap();
    let (first, again) = server.join().unwrap();
    assert_eq!(first, b"VOIS");
    assert_eq!(again, b"VOIS");
}

#[test]
fn reconnect_gives_up_after_its_attempts() {
    let (port, server) = fake_controller(|_| {});
    let mut c = connect(port);
    c.start().unwrap();
    server.join().unwrap();
    let policy = RtdeReconnectPolicy {
        attempts: 2,
        first_backoff: Duration::from_millis(1),
        max_backoff: Duration::from_millis(1),
    };
    // Nothing listens any more.
    match c.reconnect(&policy) {
        Err(RtdeReconnectError::GaveUp { attempts: 2, .. }) => {}
        other => panic!("{other:?}"),
    }
    let mut pkg = DataPackage::for_recipe(c.output_recipe().unwrap());
    assert!(
        c.receive_latest(&mut pkg, Duration::from_millis(10))
            .is_err()
    );
}

#[test]
fn silence_is_a_timeout_and_a_closed_socket_is_closed() {
    let (port, server) = fake_controller(|s| {
        thread::sleep(Duration::from_millis(300));
        s.write_all(&data(7, 1.0, 0.0, 7)).unwrap();
        thread::sleep(Duration::from_millis(50));
        // Socket dropped here: the controller is gone.
    });
    let mut c = connect(port);
    c.start().unwrap();
    let mut pkg = DataPackage::for_recipe(c.output_recipe().unwrap());
    assert!(matches!(
        c.receive_latest(&mut pkg, Duration::from_millis(100)),
        Err(RtdeReceiveError::Link(RtdeLinkError::Timeout { .. }))
    ));
    c.receive_latest(&mut pkg, Duration::from_secs(1)).unwrap();
    assert_eq!(pkg.values[0], RtdeValue::Double(1.0));
    server.join().unwrap();
    assert!(matches!(
        c.receive_latest(&mut pkg, Duration::from_secs(1)),
        Err(RtdeReceiveError::Link(RtdeLinkError::Closed { .. }))
    ));
}

#[test]
fn receive_before_start_is_refused() {
    let (port, server) = fake_controller(|_| {});
    let mut c = connect(port);
    let mut pkg = DataPackage::for_recipe(c.output_recipe().unwrap());
    assert!(matches!(
        c.receive_latest(&mut pkg, Duration::from_millis(10)),
        Err(RtdeReceiveError::NotStarted)
    ));
    c.start().unwrap();
    drop(c);
    server.join().unwrap();
}
