//! Virtual-bus behaviour beyond the common conformance suite: slow readers, crashed nodes,
//! several senders, tools.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use can_bus::{CanBus, CanFrame, CanId, JoinError, VirtualBusConfig, VirtualCanBus, conformance};

static COUNTER: AtomicU32 = AtomicU32::new(0);

/// Kills the child process when the test ends, also when it fails, so no helper outlives it.
struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn unique_bus(test: &str) -> String {
    format!(
        "t{}-{}-{test}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

fn frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::new(CanId::Standard(id), data).unwrap()
}

#[test]
fn slow_reader_loses_the_oldest_frames_and_counts_them() {
    let bus = unique_bus("slow");
    let config = VirtualBusConfig {
        max_nodes: 4,
        rx_queue_depth: 8,
        ..Default::default()
    };
    let mut sender = VirtualCanBus::join_with_config(&bus, "sender", &config).unwrap();
    let mut reader = VirtualCanBus::join_with_config(&bus, "reader", &config).unwrap();
    // The first frame read from a sender sets the baseline for loss counting.
    sender.send(&frame(0x100, &[100])).unwrap();
    assert_eq!(reader.try_recv().unwrap(), Some(frame(0x100, &[100])));
    for index in 0..20u8 {
        // The sender never blocks on the reader, as on a real bus.
        sender.send(&frame(0x100, &[index])).unwrap();
    }
    let mut received = Vec::new();
    while let Some(f) = reader.try_recv().unwrap() {
        received.push(f.data()[0]);
    }
    assert_eq!(received, (12..20).collect::<Vec<u8>>(), "newest 8 survive");
    assert_eq!(reader.lost_frame_count(), 12);
}

#[test]
fn frames_of_several_senders_come_out_in_send_order() {
    let bus = unique_bus("order");
    let mut a = VirtualCanBus::join(&bus, "a").unwrap();
    let mut b = VirtualCanBus::join(&bus, "b").unwrap();
    let mut reader = VirtualCanBus::join(&bus, "reader").unwrap();
    // Alternating senders: iceoryx2 queues per sender, the node restores the bus order.
    let mut expected = Vec::new();
    for index in 0..40u8 {
        let f = frame(0x200 + u16::from(index % 2), &[index]);
        if index % 2 == 0 {
            a.send(&f)
        } else {
            b.send(&f)
        }
        .unwrap();
        expected.push(f);
    }
    let received: Vec<CanFrame> = std::iter::from_fn(|| reader.try_recv().unwrap()).collect();
    assert_eq!(received, expected);
}

#[test]
fn a_killed_process_does_not_keep_its_place_on_the_bus() {
    let bus = unique_bus("crash");
    let config = VirtualBusConfig {
        max_nodes: 2,
        rx_queue_depth: 16,
        ..Default::default()
    };
    let mut local = VirtualCanBus::join_with_config(&bus, "local", &config).unwrap();
    let mut peer = KillOnDrop(
        Command::new(env!("CARGO_BIN_EXE_vcan"))
            .args(["echo", &bus, "--max-nodes", "2", "--queue-depth", "16"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let ready = local.recv_timeout(conformance::RECEIVE_TIMEOUT).unwrap();
    assert_eq!(ready.map(|f| f.id()), Some(conformance::PEER_READY_ID));
    // With the peer alive the bus is full.
    assert!(matches!(
        VirtualCanBus::join_with_config(&bus, "third", &config),
        Err(JoinError::BusFull { .. })
    ));
    peer.0.kill().unwrap(); // SIGKILL: no chance to clean up
    peer.0.wait().unwrap();
    // Joining cleans up dead nodes, so the slot is free again and the bus still works.
    let mut replacement = VirtualCanBus::join_with_config(&bus, "replacement", &config)
        .expect("the dead node's ports are reclaimed");
    replacement.send(&frame(0x42, &[1])).unwrap();
    assert_eq!(
        local.recv_timeout(conformance::RECEIVE_TIMEOUT).unwrap(),
        Some(frame(0x42, &[1]))
    );
}

#[test]
fn nodes_with_different_sizes_are_refused_with_a_clear_error() {
    let bus = unique_bus("sizes");
    let small = VirtualBusConfig {
        max_nodes: 2,
        rx_queue_depth: 4,
        ..Default::default()
    };
    let _first = VirtualCanBus::join_with_config(&bus, "first", &small).unwrap();
    let error = VirtualCanBus::join(&bus, "second").err().expect("refused");
    assert!(matches!(error, JoinError::Incompatible { .. }), "{error:?}");
    assert!(error.to_string().contains(&bus));
}

#[test]
fn invalid_node_names_are_refused() {
    let bus = unique_bus("nodename");
    let error = VirtualCanBus::join(&bus, &"n".repeat(5000))
        .err()
        .expect("refused");
    assert!(
        matches!(error, JoinError::InvalidNodeName { .. }),
        "{error:?}"
    );
}

#[test]
fn vcan_send_and_dump_speak_cansend_notation() {
    let bus = unique_bus("tools");
    let mut dump = KillOnDrop(
        Command::new(env!("CARGO_BIN_EXE_vcan"))
            .args(["dump", &bus])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    // Wait until the dump node is on the bus: then a sender's frames reach it.
    let mut probe = VirtualCanBus::join(&bus, "probe").unwrap();
    let stdout = dump.0.stdout.take().unwrap();
    let mut lines = BufReader::new(stdout).lines();
    // The dump node may not exist yet; send a marker until it shows up in its output.
    let marker = frame(0x7FF, &[]);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in lines.by_ref() {
            if tx.send(line.unwrap_or_default()).is_err() {
                break;
            }
        }
    });
    let first = loop {
        probe.send(&marker).unwrap();
        if let Ok(line) = rx.recv_timeout(Duration::from_millis(50)) {
            break line;
        }
    };
    assert!(first.ends_with("7FF#"), "{first}");
    let status = Command::new(env!("CARGO_BIN_EXE_vcan"))
        .args(["send", &bus, "00000413#DEADBEEF"])
        .status()
        .unwrap();
    assert!(status.success());
    let second = loop {
        let line = rx
            .recv_timeout(conformance::RECEIVE_TIMEOUT)
            .expect("dump output");
        if !line.ends_with("7FF#") {
            break line;
        }
    };
    assert!(second.ends_with("00000413#DEADBEEF"), "{second}");
    drop(dump);
    let bad = Command::new(env!("CARGO_BIN_EXE_vcan"))
        .args(["send", &bus, "800#00"])
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("out of range"));
}
