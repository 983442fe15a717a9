//! A userspace CAN bus that processes on one host join by name, on iceoryx2 publish-subscribe.
//!
//! Design (details and limits in `docs/can-bus.md`):
//! - one publish-subscribe service `grop/can/<bus>/frames` carrying [`WireFrame`]s; every node
//!   owns one publisher and one subscriber on it, so every node gets every frame, its own
//!   included; a node drops its own frames by the sender key stamped into each frame;
//! - one event service `grop/can/<bus>/wake`: a sender notifies after publishing, so that
//!   `recv_timeout` sleeps in the listener instead of polling;
//! - iceoryx2 keeps one queue per (publisher, subscriber) pair and drains them connection by
//!   connection, so a node collects everything available into a small reorder buffer and hands
//!   frames out in send-timestamp order (CLOCK_MONOTONIC, host-wide), which restores one bus-wide
//!   order for frames that were already published;
//! - a reader that falls `rx_queue_depth` frames behind one sender loses that sender's oldest
//!   frames (safe overflow: a sender never blocks on a slow reader, as on a real bus); the
//!   per-sender sequence number makes the loss visible in [`VirtualCanBus::lost_frame_count`];
//! - per-sender state is a fixed-size table ([`PEERS_PER_NODE`] x `max_nodes` senders, the least
//!   recently heard evicted and counted in [`VirtualCanBus::evicted_peer_count`]) with wrapping
//!   sequence arithmetic, since keys and sequence numbers come from other processes.
#![allow(
    unsafe_code,
    reason = "one libc call on the bus's own sockets (see the SAFETY comment)"
)]

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::{event, publish_subscribe};

use crate::os::{monotonic_ns, wait_readable};
use crate::peer_table::PeerTable;
use crate::{CanBus, CanFrame, CanId, MAX_DATA_LEN, RecvError, SendError};

type Ipc = ipc_threadsafe::Service;

/// Bit 31 of [`WireFrame::raw_id`] marks an extended id (as in Linux `CAN_EFF_FLAG`).
const EXTENDED_FLAG: u32 = 0x8000_0000;

/// Prefix of every service the virtual bus creates.
const SERVICE_PREFIX: &str = "grop/can/";

/// Longest accepted bus name, so that the service names stay well inside iceoryx2's limit.
const MAX_BUS_NAME_LEN: usize = 64;

/// Senders a node keeps sequence state for, per node the bus admits: nodes that leave and
/// join again (a restarted process) come back under new keys, so the table holds a few
/// generations of them before the least recently heard is evicted.
pub const PEERS_PER_NODE: usize = 4;

/// One frame as it travels through shared memory. Layout is part of the bus protocol: nodes of
/// different builds must agree on it, hence the explicit type name with a version.
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_can_bus::WireFrame/v1")]
pub(crate) struct WireFrame {
    /// CLOCK_MONOTONIC at send, nanoseconds; orders frames of different senders.
    sent_at_ns: u64,
    /// Unique per node (process id and per-process counter); filters self-reception.
    sender_key: u64,
    /// Per-sender sequence number starting at 0; gaps are lost frames.
    seq: u64,
    /// CAN id, bit 31 set for extended ids.
    raw_id: u32,
    /// Number of valid bytes in `data`.
    len: u8,
    data: [u8; MAX_DATA_LEN],
    _reserved: [u8; 3],
}

impl WireFrame {
    fn encode(frame: &CanFrame, sender_key: u64, seq: u64) -> Self {
        let raw_id = match frame.id() {
            CanId::Standard(raw) => u32::from(raw),
            CanId::Extended(raw) => raw | EXTENDED_FLAG,
        };
        let mut data = [0u8; MAX_DATA_LEN];
        data[..frame.data().len()].copy_from_slice(frame.data());
        Self {
            sent_at_ns: monotonic_ns(),
            sender_key,
            seq,
            raw_id,
            len: frame.dlc(),
            data,
            _reserved: [0; 3],
        }
    }

    /// Checks everything another process put here: this is external data.
    fn decode(&self) -> Result<CanFrame, String> {
        let id = if self.raw_id & EXTENDED_FLAG != 0 {
            CanId::Extended(self.raw_id & !EXTENDED_FLAG)
        } else {
            let raw = u16::try_from(self.raw_id)
                .map_err(|_| format!("standard id 0x{:X} is out of range", self.raw_id))?;
            CanId::Standard(raw)
        };
        let len = usize::from(self.len);
        let data = self
            .data
            .get(..len)
            .ok_or_else(|| format!("data length {len} is above 8"))?;
        CanFrame::new(id, data).map_err(|error| error.to_string())
    }
}

/// Bytes of a [`WireFrame`] in shared memory.
pub(crate) const WIRE_FRAME_LEN: usize = core::mem::size_of::<WireFrame>();

impl WireFrame {
    /// The frame as another process left it in shared memory: the `repr(C)` layout, native byte
    /// order. Every bit pattern is a valid `WireFrame` (integers and bytes only).
    fn from_shared_bytes(bytes: &[u8; WIRE_FRAME_LEN]) -> Self {
        fn at<const N: usize>(bytes: &[u8], offset: usize) -> [u8; N] {
            let mut out = [0u8; N];
            out.copy_from_slice(&bytes[offset..offset + N]);
            out
        }
        use core::mem::offset_of;
        Self {
            sent_at_ns: u64::from_ne_bytes(at(bytes, offset_of!(Self, sent_at_ns))),
            sender_key: u64::from_ne_bytes(at(bytes, offset_of!(Self, sender_key))),
            seq: u64::from_ne_bytes(at(bytes, offset_of!(Self, seq))),
            raw_id: u32::from_ne_bytes(at(bytes, offset_of!(Self, raw_id))),
            len: bytes[offset_of!(Self, len)],
            data: at(bytes, offset_of!(Self, data)),
            _reserved: at(bytes, offset_of!(Self, _reserved)),
        }
    }
}

/// Fuzzing entry point, not an API: decodes `bytes` (at most the first [`WireFrame`]'s worth,
/// zero-filled when shorter) exactly as a receiving node decodes a frame from shared memory, and
/// for a frame that decodes, checks that sending it again yields the same frame. Returns the
/// decoded frame.
#[doc(hidden)]
pub fn fuzz_decode_wire_frame(bytes: &[u8]) -> Result<CanFrame, String> {
    let mut raw = [0u8; WIRE_FRAME_LEN];
    let n = bytes.len().min(WIRE_FRAME_LEN);
    raw[..n].copy_from_slice(&bytes[..n]);
    let wire = WireFrame::from_shared_bytes(&raw);
    let frame = wire.decode()?;
    let again = WireFrame::encode(&frame, wire.sender_key, wire.seq).decode();
    if again != Ok(frame) {
        return Err(format!("{frame:?} re-encodes to {again:?}"));
    }
    Ok(frame)
}

/// Sizes of the bus. Every process on one bus must use the same values: the first node creates
/// the services with them and later nodes are refused if they ask for more.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VirtualBusConfig {
    /// Most nodes on the bus at once.
    pub max_nodes: usize,
    /// Frames a node buffers per sender before that sender's oldest frames are dropped.
    pub rx_queue_depth: usize,
    /// How long a leaving node stays after its last send (local setting, need not match).
    /// A receiver maps a sender's shared memory lazily, on its next receive; frames of a sender
    /// that is gone before that are lost, so a node that just sent waits this long in `drop`.
    pub leave_linger: Duration,
}

impl Default for VirtualBusConfig {
    fn default() -> Self {
        Self {
            max_nodes: 16,
            rx_queue_depth: 256,
            leave_linger: Duration::from_millis(50),
        }
    }
}

/// Why joining a virtual bus failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum JoinError {
    /// The bus name is empty, too long, or holds characters other than ASCII letters, digits,
    /// `-`, `_` and `.`.
    #[error(
        "virtual CAN bus name {name:?} is invalid: use 1..={MAX_BUS_NAME_LEN} ASCII letters, digits, '-', '_' or '.'"
    )]
    InvalidBusName {
        /// The rejected name.
        name: String,
    },
    /// iceoryx2 refused the node name.
    #[error("virtual CAN node name {name:?} is invalid: {detail}")]
    InvalidNodeName {
        /// The rejected name.
        name: String,
        /// iceoryx2's reason.
        detail: String,
    },
    /// The bus already has `max_nodes` nodes.
    #[error("virtual CAN bus {bus} is full (at most {max_nodes} nodes)")]
    BusFull {
        /// Bus name.
        bus: String,
        /// The configured limit.
        max_nodes: usize,
    },
    /// The bus exists with other sizes or another frame layout (another build or config).
    #[error("virtual CAN bus {bus} exists but is incompatible with this node: {detail}")]
    Incompatible {
        /// Bus name.
        bus: String,
        /// iceoryx2's reason.
        detail: String,
    },
    /// Another iceoryx2 failure while setting up the node, named by `stage`.
    #[error("joining virtual CAN bus {bus} failed while {stage}: {detail}")]
    Ipc {
        /// Bus name.
        bus: String,
        /// What was being set up.
        stage: &'static str,
        /// iceoryx2's reason.
        detail: String,
    },
}

/// A received frame waiting in the reorder buffer.
#[derive(Clone, Copy)]
struct Pending {
    sent_at_ns: u64,
    sender_key: u64,
    seq: u64,
    frame: CanFrame,
}

impl Pending {
    /// Bus order: send time, ties broken by sender and per-sender sequence number.
    fn order_key(&self) -> (u64, u64, u64) {
        (self.sent_at_ns, self.sender_key, self.seq)
    }
}

impl PartialEq for Pending {
    fn eq(&self, other: &Self) -> bool {
        self.order_key() == other.order_key()
    }
}
impl Eq for Pending {}
impl PartialOrd for Pending {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Pending {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.order_key().cmp(&other.order_key())
    }
}

/// One node on a virtual CAN bus shared by every process on this host that joins the same name.
///
/// ```no_run
/// use std::time::Duration;
/// use can_bus::{CanBus, CanFrame, CanId, VirtualCanBus};
/// let mut driver = VirtualCanBus::join("hil", "rmp-driver")?;
/// driver.send(&CanFrame::new(CanId::Standard(0x500), &[0; 8])?)?;
/// let reply = driver.recv_timeout(Duration::from_millis(20))?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct VirtualCanBus {
    bus_name: String,
    node_name: String,
    sender_key: u64,
    next_seq: u64,
    publisher: iceoryx2::port::publisher::Publisher<Ipc, WireFrame, ()>,
    subscriber: iceoryx2::port::subscriber::Subscriber<Ipc, WireFrame, ()>,
    notifier: iceoryx2::port::notifier::Notifier<Ipc>,
    listener: iceoryx2::port::listener::Listener<Ipc>,
    /// The listener's socket, valid as long as `listener` lives.
    listener_fd: i32,
    reorder: BinaryHeap<Reverse<Pending>>,
    reorder_capacity: usize,
    peers: PeerTable,
    lost_frames: u64,
    notify_failures: u64,
    last_send: Option<Instant>,
    leave_linger: Duration,
    // Dropped last: ports first, then the services, then the node (field order is drop order).
    _frames_service: publish_subscribe::PortFactory<Ipc, WireFrame, ()>,
    _wake_service: event::PortFactory<Ipc>,
    _node: Node<Ipc>,
}

static NODES_IN_PROCESS: AtomicU32 = AtomicU32::new(0);

impl VirtualCanBus {
    /// Joins (creating it if needed) the virtual bus `bus_name` as `node_name`, with the default
    /// [`VirtualBusConfig`]. The node receives frames sent after this call returns.
    pub fn join(bus_name: &str, node_name: &str) -> Result<Self, JoinError> {
        Self::join_with_config(bus_name, node_name, &VirtualBusConfig::default())
    }

    /// Like [`join`](Self::join) with explicit sizes; all nodes of a bus must use the same.
    #[allow(
        clippy::too_many_lines,
        reason = "the join handshake step by step, each failure named where it happens"
    )]
    pub fn join_with_config(
        bus_name: &str,
        node_name: &str,
        config: &VirtualBusConfig,
    ) -> Result<Self, JoinError> {
        let valid_bus_name = !bus_name.is_empty()
            && bus_name.len() <= MAX_BUS_NAME_LEN
            && bus_name
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_' || b == b'.');
        if !valid_bus_name {
            return Err(JoinError::InvalidBusName {
                name: bus_name.to_owned(),
            });
        }
        let bus = || bus_name.to_owned();
        let ipc = |stage: &'static str| {
            move |error: &dyn std::fmt::Debug| JoinError::Ipc {
                bus: bus_name.to_owned(),
                stage,
                detail: format!("{error:?}"),
            }
        };
        let max_nodes = config.max_nodes.max(2);
        let rx_queue_depth = config.rx_queue_depth.max(1);

        let iox_node_name =
            NodeName::new(node_name).map_err(|error| JoinError::InvalidNodeName {
                name: node_name.to_owned(),
                detail: format!("{error:?}"),
            })?;
        let node = NodeBuilder::new()
            .name(&iox_node_name)
            // A driver process must keep its own Ctrl-C / SIGTERM behaviour.
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Ipc>()
            .map_err(|e| ipc("creating the iceoryx2 node")(&e))?;
        // A crashed process leaves its ports registered; reclaim them so the bus does not fill up.
        let cleanup = node.try_cleanup_dead_nodes();
        if cleanup.cleanups > 0 || cleanup.failed_cleanups > 0 {
            log::info!(
                "virtual CAN bus {bus_name}: cleaned up {} dead nodes ({} failed)",
                cleanup.cleanups,
                cleanup.failed_cleanups
            );
        }

        let frames_name =
            service_name(bus_name, "frames").map_err(|e| ipc("naming the frame service")(&e))?;
        let frames_service = node
            .service_builder(&frames_name)
            .publish_subscribe::<WireFrame>()
            .max_publishers(max_nodes)
            .max_subscribers(max_nodes)
            .max_nodes(max_nodes)
            .subscriber_max_buffer_size(rx_queue_depth)
            .subscriber_max_borrowed_samples(1)
            .history_size(0)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|error| match crate::os::service_open_failure(&error) {
                crate::os::ServiceOpenFailure::NodeLimit => JoinError::BusFull {
                    bus: bus(),
                    max_nodes,
                },
                crate::os::ServiceOpenFailure::Incompatible(detail) => {
                    JoinError::Incompatible { bus: bus(), detail }
                }
                crate::os::ServiceOpenFailure::Other => ipc("opening the frame service")(&error),
            })?;

        let wake_name =
            service_name(bus_name, "wake").map_err(|e| ipc("naming the wake-up service")(&e))?;
        let wake_service = node
            .service_builder(&wake_name)
            .event()
            .max_notifiers(max_nodes)
            .max_listeners(max_nodes)
            .max_nodes(max_nodes)
            .open_or_create()
            .map_err(|e| ipc("opening the wake-up service")(&e))?;

        // Listener and subscriber first: nothing sent after join() returns may be missed.
        let listener = wake_service
            .listener_builder()
            .create()
            .map_err(|e| ipc("creating the wake-up listener")(&e))?;
        let subscriber = frames_service
            .subscriber_builder()
            .buffer_size(rx_queue_depth)
            .create()
            .map_err(|error| match error {
                iceoryx2::port::subscriber::SubscriberCreateError::ExceedsMaxSupportedSubscribers => {
                    JoinError::BusFull { bus: bus(), max_nodes }
                }
                other => ipc("creating the frame subscriber")(&other),
            })?;
        let publisher = frames_service
            .publisher_builder()
            .max_loaned_samples(1)
            .create()
            .map_err(|error| match error {
                iceoryx2::port::publisher::PublisherCreateError::ExceedsMaxSupportedPublishers => {
                    JoinError::BusFull {
                        bus: bus(),
                        max_nodes,
                    }
                }
                other => ipc("creating the frame publisher")(&other),
            })?;
        let notifier = wake_service
            .notifier_builder()
            .create()
            .map_err(|e| ipc("creating the wake-up notifier")(&e))?;

        // SAFETY: the descriptor belongs to `listener`, which this node owns and keeps open for
        // its whole life; it is only ever polled, never closed or read through this copy.
        let listener_fd = unsafe { listener.file_descriptor().native_handle() };
        let counter = NODES_IN_PROCESS.fetch_add(1, Ordering::Relaxed);
        let sender_key = (u64::from(std::process::id()) << 32) | u64::from(counter);
        // Room for a full queue from a handful of senders; draining stops when it is full.
        let reorder_capacity = rx_queue_depth.saturating_mul(4);
        log::debug!("node {node_name} joined virtual CAN bus {bus_name} (key {sender_key:016X})");
        Ok(Self {
            bus_name: bus_name.to_owned(),
            node_name: node_name.to_owned(),
            sender_key,
            next_seq: 0,
            publisher,
            subscriber,
            notifier,
            listener,
            listener_fd,
            reorder: BinaryHeap::with_capacity(reorder_capacity),
            reorder_capacity,
            peers: PeerTable::new(max_nodes.saturating_mul(PEERS_PER_NODE)),
            lost_frames: 0,
            notify_failures: 0,
            last_send: None,
            leave_linger: config.leave_linger,
            _frames_service: frames_service,
            _wake_service: wake_service,
            _node: node,
        })
    }

    /// The bus this node joined.
    pub fn bus_name(&self) -> &str {
        &self.bus_name
    }

    /// This node's name.
    pub fn node_name(&self) -> &str {
        &self.node_name
    }

    /// Frames from other nodes this node never saw because it fell more than `rx_queue_depth`
    /// frames behind their sender, counted from gaps in the per-sender sequence numbers. Losses
    /// before the first frame read from a sender cannot be told from frames sent before this
    /// node joined, so they are not counted.
    pub fn lost_frame_count(&self) -> u64 {
        self.lost_frames
    }

    /// Senders dropped from this node's per-sender table to keep it within
    /// [`PEERS_PER_NODE`] x `max_nodes` entries (least recently heard first). A dropped sender
    /// heard again starts afresh: a gap across its eviction is not counted as lost.
    pub fn evicted_peer_count(&self) -> u64 {
        self.peers.evicted()
    }

    /// Moves every frame iceoryx2 holds for us into the reorder buffer (until it is full).
    fn drain_subscriber(&mut self) -> Result<(), RecvError> {
        while self.reorder.len() < self.reorder_capacity {
            let sample = self.subscriber.receive().map_err(|error| RecvError::Ipc {
                bus: self.bus_name.clone(),
                detail: format!("{error:?}"),
            })?;
            let Some(sample) = sample else {
                return Ok(());
            };
            let wire = *sample.payload();
            drop(sample);
            if wire.sender_key == self.sender_key {
                continue; // our own frame: a bus node does not receive what it sent
            }
            let lost = self.peers.observe(wire.sender_key, wire.seq);
            self.lost_frames = self.lost_frames.saturating_add(lost);
            let frame = wire.decode().map_err(|detail| RecvError::Malformed {
                bus: self.bus_name.clone(),
                sender: format!("node key {:016X}", wire.sender_key),
                detail,
            })?;
            self.reorder.push(Reverse(Pending {
                sent_at_ns: wire.sent_at_ns,
                sender_key: wire.sender_key,
                seq: wire.seq,
                frame,
            }));
        }
        Ok(())
    }
}

impl CanBus for VirtualCanBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        let wire = WireFrame::encode(frame, self.sender_key, self.next_seq);
        self.publisher
            .send_copy(wire)
            .map_err(|error| SendError::Ipc {
                bus: self.bus_name.clone(),
                detail: format!("{error:?}"),
            })?;
        self.next_seq += 1;
        self.last_send = Some(Instant::now());
        // The frame is on the bus; a failed wake-up only delays a sleeping reader until its
        // timeout, so it is logged, not returned (an error would claim the frame was not sent).
        if let Err(error) = self.notifier.notify() {
            self.notify_failures += 1;
            if self.notify_failures.is_power_of_two() {
                log::warn!(
                    "virtual CAN bus {}: wake-up notification failed ({} times): {error:?}",
                    self.bus_name,
                    self.notify_failures
                );
            }
        }
        Ok(())
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        self.drain_subscriber()?;
        Ok(self.reorder.pop().map(|Reverse(pending)| pending.frame))
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, RecvError> {
        let start = Instant::now();
        loop {
            // Clear wake-ups first, then look: a frame published after the look comes with a
            // notification that ends the wait below, so none is missed and nothing spins.
            self.listener
                .try_wait(|_| {})
                .map_err(|error| self.ipc_recv_error(&error))?;
            if let Some(frame) = self.try_recv()? {
                return Ok(Some(frame));
            }
            let Some(remaining) = timeout.checked_sub(start.elapsed()) else {
                return Ok(None);
            };
            if remaining.is_zero() {
                return Ok(None);
            }
            // poll(2) on the listener's socket instead of `Listener::timed_wait`: the latter
            // uses a socket receive timeout, which the kernel rounds up to whole scheduler ticks
            // (4-8 ms measured for a 200 us timeout); ppoll sleeps on a high-resolution timer.
            wait_readable(self.listener_fd, remaining).map_err(|error| RecvError::Ipc {
                bus: self.bus_name.clone(),
                detail: format!("waiting for a wake-up: {error}"),
            })?;
        }
    }
}

impl VirtualCanBus {
    fn ipc_recv_error(&self, error: &dyn std::fmt::Debug) -> RecvError {
        RecvError::Ipc {
            bus: self.bus_name.clone(),
            detail: format!("{error:?}"),
        }
    }
}

impl Drop for VirtualCanBus {
    fn drop(&mut self) {
        if let Some(last_send) = self.last_send {
            if let Some(rest) = self.leave_linger.checked_sub(last_send.elapsed()) {
                std::thread::sleep(rest);
            }
        }
    }
}

fn service_name(
    bus_name: &str,
    what: &str,
) -> Result<ServiceName, iceoryx2::service::service_name::ServiceNameError> {
    ServiceName::new(&format!("{SERVICE_PREFIX}{bus_name}/{what}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_frames_round_trip_and_reject_garbage() {
        for frame in [
            CanFrame::new(CanId::Standard(0x7FF), &[1, 2, 3]).unwrap(),
            CanFrame::new(CanId::Extended(0x1FFF_FFFF), &[9; 8]).unwrap(),
            CanFrame::new(CanId::Extended(0x123), &[]).unwrap(),
        ] {
            assert_eq!(WireFrame::encode(&frame, 1, 2).decode(), Ok(frame));
        }
        let mut wire = WireFrame::encode(&CanFrame::new(CanId::Standard(1), &[]).unwrap(), 1, 0);
        wire.len = 9;
        assert!(wire.decode().unwrap_err().contains("length 9"));
        wire.len = 0;
        wire.raw_id = 0x800;
        assert!(wire.decode().unwrap_err().contains("0x800"));
        wire.raw_id = 0xFFFF_FFFF;
        assert!(wire.decode().is_err());
    }

    #[test]
    fn shared_memory_bytes_read_back_as_the_frame_that_was_sent() {
        let frame = CanFrame::new(CanId::Extended(0x1234_5678), &[1, 2, 3, 4, 5]).unwrap();
        let wire = WireFrame::encode(&frame, 0xABCD, 7);
        // What the publisher copies into shared memory, byte for byte.
        let mut bytes = Vec::new();
        bytes.extend_from_slice(&wire.sent_at_ns.to_ne_bytes());
        bytes.extend_from_slice(&wire.sender_key.to_ne_bytes());
        bytes.extend_from_slice(&wire.seq.to_ne_bytes());
        bytes.extend_from_slice(&wire.raw_id.to_ne_bytes());
        bytes.push(wire.len);
        bytes.extend_from_slice(&wire.data);
        bytes.extend_from_slice(&wire._reserved);
        assert_eq!(bytes.len(), WIRE_FRAME_LEN);
        let back = WireFrame::from_shared_bytes(&bytes.clone().try_into().unwrap());
        assert_eq!((back.sender_key, back.seq), (0xABCD, 7));
        assert_eq!(fuzz_decode_wire_frame(&bytes), Ok(frame));
        assert!(fuzz_decode_wire_frame(&[0xFF; WIRE_FRAME_LEN]).is_err());
        assert_eq!(
            fuzz_decode_wire_frame(&[]),
            Ok(CanFrame::new(CanId::Standard(0), &[]).unwrap())
        );
    }

    /// A node with a hand-made publisher: sends wire frames with any sender key and sequence
    /// number, as a hostile or broken process on the same bus could.
    fn forge(peer: &VirtualCanBus, sender_key: u64, seq: u64) {
        let frame = CanFrame::new(CanId::Standard(0x123), &[1]).unwrap();
        peer.publisher
            .send_copy(WireFrame::encode(&frame, sender_key, seq))
            .unwrap();
    }

    fn unique_bus(test: &str) -> String {
        format!("u{}-{test}", std::process::id())
    }

    #[test]
    fn hostile_sequence_numbers_neither_panic_nor_overflow_the_loss_count() {
        let bus = unique_bus("seq");
        let mut victim = VirtualCanBus::join(&bus, "victim").unwrap();
        let attacker = VirtualCanBus::join(&bus, "attacker").unwrap();
        // Half-range jumps up to the top of the range, a wrap to 0, jumps back and forth.
        let half = 1u64 << 63;
        for seq in [0, half - 1, u64::MAX - 1, u64::MAX, 0, 5, 3, u64::MAX, 2] {
            forge(&attacker, 0xBAD, seq);
            assert!(victim.try_recv().unwrap().is_some(), "seq {seq}");
        }
        // Gaps: half-2 and half-1 (the two half-range jumps), 4 (0 -> 5), 2 (MAX -> 2, across
        // the wrap); 5 -> 3 is a step back, and 3 -> MAX, more than half the range ahead, reads
        // as one too. The sum passes u64::MAX: it saturates, never wraps or panics.
        assert_eq!(victim.lost_frame_count(), u64::MAX);
    }

    #[test]
    fn the_peer_table_is_bounded_and_evicts_the_least_recently_heard() {
        let bus = unique_bus("peers");
        let config = VirtualBusConfig {
            max_nodes: 4,
            ..VirtualBusConfig::default()
        };
        let mut victim = VirtualCanBus::join_with_config(&bus, "victim", &config).unwrap();
        let attacker = VirtualCanBus::join_with_config(&bus, "attacker", &config).unwrap();
        let bound = victim.peers.capacity();
        assert_eq!(bound, 4 * PEERS_PER_NODE);
        // A steady peer, then a stream of invented sender keys (a process cycling its keys, or
        // a hostile one), then the steady peer again.
        forge(&attacker, 1, 0);
        assert!(victim.try_recv().unwrap().is_some());
        for key in 0..1000u64 {
            forge(&attacker, 1_000_000 + key, 0);
            assert!(victim.try_recv().unwrap().is_some());
            assert!(victim.peers.len() <= bound);
        }
        assert_eq!(victim.peers.len(), bound);
        assert_eq!(victim.evicted_peer_count(), 1001 - bound as u64);
        // The steady peer was the least recently heard and went first: its next frame is a
        // first frame again, so no loss is counted across the eviction.
        forge(&attacker, 1, 10);
        assert!(victim.try_recv().unwrap().is_some());
        assert_eq!(victim.lost_frame_count(), 0);
    }

    #[test]
    fn bad_bus_names_are_rejected_before_touching_iceoryx2() {
        for name in ["", "a/b", "with space", &"x".repeat(65)] {
            assert!(matches!(
                VirtualCanBus::join(name, "node"),
                Err(JoinError::InvalidBusName { .. })
            ));
        }
    }
}
