//! The RTDE client against a scripted controller written byte by byte here (independent of
//! the simulator's encoder, so a shared codec bug cannot hide).

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::thread;
use std::time::Duration;

use ur5e::rtde::{
    DataPackage, RtdeClient, RtdeLinkError, RtdeReceiveError, RtdeSetupError, RtdeTimeouts,
    RtdeType, RtdeValue,
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
        loop {
            let (ty, payload) = read_request(&mut s);
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
                b'I' => s.write_all(&pkg(b'I', b"\x01IN_USE")).unwrap(),
                b'S' => {
                    s.write_all(&pkg(b'S', &[1])).unwrap();
                    break;
                }
                other => panic!("unexpected request {other}"),
            }
        }
        after_start(&mut s);
    });
    (port, handle)
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

#[test]
fn a_package_that_does_not_match_the_recipe_is_an_error_not_a_panic() {
    let (port, server) = fake_controller(|s| {
        // Recipe says 8 + 48 + 4 bytes; send 8 + 48 only.
        let mut p = vec![7u8];
        p.extend_from_slice(&[0u8; 56]);
        s.write_all(&pkg(b'U', &p)).unwrap();
        thread::sleep(Duration::from_millis(200));
    });
    let mut c = connect(port);
    c.start().unwrap();
    let mut pkg = DataPackage::for_recipe(c.output_recipe().unwrap());
    assert!(matches!(
        c.receive_latest(&mut pkg, Duration::from_secs(1)),
        Err(RtdeReceiveError::BadPackage { recipe_id: 7, .. })
    ));
    server.join().unwrap();
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
