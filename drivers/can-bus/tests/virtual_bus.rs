//! Virtual-bus behaviour beyond the common conformance suite: slow readers, several senders,
//! refused joins. Crashed nodes and the `vcan` tool: `drivers/vcan-tool/tests/cross_process.rs`.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::sync::atomic::{AtomicU32, Ordering};

use can_bus::{CanBus, CanFrame, CanId, JoinError, VirtualBusConfig, VirtualCanBus};

static COUNTER: AtomicU32 = AtomicU32::new(0);

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
