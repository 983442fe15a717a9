//! The virtual CAN bus across processes, with the `vcan` binary of this crate as the other
//! process: the conformance suite against its echo peer, a SIGKILLed node's slot reclaimed, and
//! `vcan send` / `vcan dump` in candump notation.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

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

/// A bus name no other test (in this or another process) uses: pid + counter + test name.
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
fn virtual_bus_conforms_across_two_processes() {
    let bus = unique_bus("xproc");
    let mut local = VirtualCanBus::join(&bus, "local").unwrap();
    // Joined before the peer starts, so its READY frame cannot be missed.
    let mut peer = KillOnDrop(
        Command::new(env!("CARGO_BIN_EXE_vcan"))
            .args(["echo", &bus, "--idle-timeout-ms", "10000"])
            .stdout(Stdio::null())
            .spawn()
            .expect("spawn the vcan echo peer"),
    );
    let result = conformance::against_echo_peer(&mut local, 200);
    let status = peer.0.wait().expect("wait for the echo peer");
    result.unwrap();
    assert!(status.success(), "echo peer exited with {status}");
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
