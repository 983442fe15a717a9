//! The conformance suite against every backend: MemoryBus, VirtualCanBus within one process,
//! SocketCanBus on vcan0 (skipped, and saying so, where it does not exist). Across two processes
//! (with the `vcan echo` peer) in `drivers/vcan-tool/tests/cross_process.rs`.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::io::Write;
use std::sync::atomic::{AtomicU32, Ordering};

use can_bus::{
    MemoryBus, SocketCanBus, VirtualBusConfig, VirtualCanBus, conformance, interface_exists,
};

static COUNTER: AtomicU32 = AtomicU32::new(0);

/// A bus name no other test (in this or another process) uses: pid + counter + test name.
fn unique_bus(test: &str) -> String {
    format!(
        "t{}-{}-{test}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

fn virtual_join(bus: &str) -> impl FnMut() -> VirtualCanBus {
    let bus = bus.to_owned();
    let mut node_index = 0u32;
    move || {
        node_index += 1;
        VirtualCanBus::join(&bus, &format!("node{node_index}")).expect("join the virtual bus")
    }
}

#[test]
fn memory_bus_conforms() {
    let bus = MemoryBus::new();
    conformance::run_all(|| bus.join(), 200).unwrap();
}

#[test]
fn virtual_bus_conforms_within_one_process() {
    let bus = unique_bus("inproc");
    conformance::run_all(virtual_join(&bus), 200).unwrap();
}

#[test]
fn virtual_bus_refuses_a_node_beyond_max_nodes() {
    let bus = unique_bus("full");
    let config = VirtualBusConfig {
        max_nodes: 2,
        rx_queue_depth: 8,
        ..Default::default()
    };
    let _a = VirtualCanBus::join_with_config(&bus, "a", &config).unwrap();
    let _b = VirtualCanBus::join_with_config(&bus, "b", &config).unwrap();
    let third = VirtualCanBus::join_with_config(&bus, "c", &config);
    assert!(
        matches!(third, Err(can_bus::JoinError::BusFull { .. })),
        "third node: {:?}",
        third.err()
    );
}

#[test]
fn socketcan_conforms_on_vcan0() {
    if !interface_exists("vcan0") {
        // Written past libtest's output capture, so the skip shows in every test run.
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED socketcan_conforms_on_vcan0: no vcan0 interface on this machine \
             (sudo modprobe vcan && sudo ip link add dev vcan0 type vcan && sudo ip link set up vcan0)"
        );
        return;
    }
    // Small bursts: a vcan socket's default receive buffer holds a few hundred frames.
    conformance::run_all(|| SocketCanBus::open("vcan0").expect("open vcan0"), 64).unwrap();
}

#[test]
fn socketcan_open_names_a_missing_interface() {
    // Works on every machine: without AF_CAN or without the interface, opening fails cleanly.
    let error = SocketCanBus::open("nosuchcan7")
        .err()
        .expect("no such interface");
    assert!(
        matches!(error, can_bus::OpenError::Open { .. }),
        "{error:?}"
    );
    assert!(error.to_string().contains("nosuchcan7"));
    assert!(!interface_exists("nosuchcan7"));
    assert!(!interface_exists("../lo"));
}
