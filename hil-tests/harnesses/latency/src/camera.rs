//! A camera frame across two processes: 640 x 480 RGB8 (921,600 bytes) in the runtime's
//! `CameraFrameMsg`, from the publisher starting to write it to the subscriber holding it.
//!
//! The peer process publishes; this process subscribes and records. Per frame, this process
//! writes one command byte to the peer (which transport, whether to wake the reader); the peer
//! waits `gap` (so a sleeping reader is asleep), stamps `start`, writes the frame, stamps
//! `written`, sends it. This process stamps `held` when the frame is in its hands. Both stamps
//! are CLOCK_MONOTONIC, which is host-wide. Reported: `held - start` (write + transfer) and
//! `held - written` (transfer only).
//!
//! Transports, interleaved in rounds (the order rotates each round, so machine noise hits all
//! alike):
//! * **iceoryx2**: `loan_uninit`, the image written in place in shared memory, `send`; the
//!   service sized for one publisher and one subscriber (3 samples of 3.5 MiB). The times travel
//!   in an iceoryx2 user header;
//! * **grop-ipc `publish_with`**: the runtime's generic `TopicPublisher::publish_with` on
//!   `camera/frame`, which zeroes the whole 3.5 MiB message before the image is written (what
//!   the HIL world's camera did before issue 23), and its `TopicSubscriber`;
//! * **grop-ipc `publish_frame`**: `TopicPublisher::publish_frame`, which writes the header,
//!   zeroes only the 921,600 image bytes the header describes and lets the image be written in
//!   place (what the HIL world's camera does now), and the same subscriber;
//! * **Unix socket** (stream, `write_all` / `read_exact`) and **TCP** on loopback
//!   (`TCP_NODELAY`): the same 80-byte header and 921,600 image bytes, written into a reused
//!   buffer and sent.
//!
//! Two reader modes: *polling* (the reader spins on `receive` / non-blocking `read`) and
//! *sleeping* (iceoryx2 readers sleep in `ppoll` on the event service's listener and the
//! publisher notifies after sending; socket readers block in `read`).
#![allow(
    unsafe_code,
    reason = "raw iceoryx2 loans written in place: the baseline row the product's path is compared with"
)]

use std::io::{Read, Write};
use std::mem::MaybeUninit;
use std::net::{TcpListener, TcpStream};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use grop_ipc::{CameraFrameHeader, CameraFrameMsg, IpcNode};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use crate::peer::{Peer, field};
use crate::{BenchError, Summary, ThreadUsage, names, now_ns};

/// Frame width, px.
pub const WIDTH_PX: u32 = 640;
/// Frame height, px.
pub const HEIGHT_PX: u32 = 480;
/// Image bytes per frame (RGB8).
pub const IMAGE_BYTES: usize = (WIDTH_PX * HEIGHT_PX * 3) as usize;
/// Bytes of the times a socket frame starts with (seq, start, written).
const TIMES_BYTES: usize = 24;
/// Bytes of the camera header a socket frame carries next.
const HEADER_BYTES: usize = 56;
/// Bytes per frame on a socket.
pub const STREAM_FRAME_BYTES: usize = TIMES_BYTES + HEADER_BYTES + IMAGE_BYTES;
/// Longest wait for one frame before the measurement fails.
const FRAME_TIMEOUT: Duration = Duration::from_secs(5);

type Ipc = ipc::Service;
pub(crate) type FrameService = iceoryx2::service::port_factory::publish_subscribe::PortFactory<
    Ipc,
    CameraFrameMsg,
    FrameTimes,
>;
pub(crate) type WakeService = iceoryx2::service::port_factory::event::PortFactory<Ipc>;

/// Send times carried next to the frame (an iceoryx2 user header; the first 24 bytes of a
/// socket frame).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_latency::FrameTimes/v1")]
pub struct FrameTimes {
    /// Frame counter.
    pub seq: u64,
    /// The publisher started writing the frame, CLOCK_MONOTONIC ns.
    pub start_ns: u64,
    /// The frame was written (before sending), CLOCK_MONOTONIC ns.
    pub written_ns: u64,
}

/// How a frame travels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Transport {
    /// iceoryx2 directly: loan, write in place, send.
    Iceoryx2,
    /// The runtime's grop-ipc publisher, generic `publish_with` (zeroes the 3.5 MiB message,
    /// then writes).
    GropIpc,
    /// The runtime's grop-ipc publisher, `publish_frame` (zeroes the image's bytes only).
    GropIpcFrame,
    /// Unix domain stream socket.
    UnixSocket,
    /// TCP on loopback with TCP_NODELAY.
    Tcp,
}

impl Transport {
    /// Every transport, in the report's order.
    pub const ALL: [Transport; 5] = [
        Transport::Iceoryx2,
        Transport::GropIpc,
        Transport::GropIpcFrame,
        Transport::UnixSocket,
        Transport::Tcp,
    ];

    /// Name in the report.
    pub fn label(self) -> &'static str {
        match self {
            Transport::Iceoryx2 => "iceoryx2 (loan_uninit, write in place, send)",
            Transport::GropIpc => "grop-ipc publish_with (zeroes 3.5 MiB, then writes)",
            Transport::GropIpcFrame => "grop-ipc publish_frame (zeroes the image only, writes)",
            Transport::UnixSocket => "Unix stream socket",
            Transport::Tcp => "TCP loopback (TCP_NODELAY)",
        }
    }

    /// The command byte that asks the peer for one frame on this transport.
    fn command(self, mode: WaitMode) -> u8 {
        match (self, mode) {
            (Transport::Iceoryx2, WaitMode::Polling) => b'i',
            (Transport::Iceoryx2, WaitMode::Sleeping) => b'I',
            (Transport::GropIpc, _) => b'g',
            (Transport::GropIpcFrame, _) => b'f',
            (Transport::UnixSocket, _) => b'u',
            (Transport::Tcp, _) => b't',
        }
    }
}

/// How the subscriber waits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitMode {
    /// Busy-waiting on the transport.
    Polling,
    /// Asleep until woken (iceoryx2 event, blocking socket read).
    Sleeping,
}

impl WaitMode {
    /// Name in the report.
    pub fn label(self) -> &'static str {
        match self {
            WaitMode::Polling => "polling subscriber (busy-waits)",
            WaitMode::Sleeping => "sleeping subscriber (woken by an event / blocking read)",
        }
    }
}

/// Sizes of the measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CameraConfig {
    /// Measured rounds per mode; each round sends `frames_per_round` frames on every transport.
    pub rounds: usize,
    /// Frames per transport per round.
    pub frames_per_round: usize,
    /// Frames per transport and mode before measuring (first touches of shared memory and
    /// buffers, connection set-up).
    pub warmup_frames: usize,
    /// Pause of the publisher between the command and the frame.
    pub gap: Duration,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            rounds: 10,
            frames_per_round: 50,
            warmup_frames: 30,
            gap: Duration::from_micros(300),
        }
    }
}

/// The warm-up frames of one transport in one mode: what the first frames cost while the
/// memory they are written into and read from is touched for the first time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Warmup {
    /// Warm-up frames.
    pub frames: usize,
    /// The very first frame: start of writing -> held, ns.
    pub first_frame_ns: u64,
    /// Minor page faults of the publisher over the warm-up frames.
    pub publisher_faults: u64,
    /// Minor page faults of the subscriber over the warm-up frames.
    pub subscriber_faults: u64,
}

/// One transport in one mode.
#[derive(Debug, Clone, PartialEq)]
pub struct TransportResult {
    /// The transport.
    pub transport: Transport,
    /// Its warm-up.
    pub warmup: Warmup,
    /// Publisher starts writing -> subscriber holds the frame.
    pub total: Summary,
    /// Frame written -> subscriber holds it (not measurable for grop-ipc, whose publisher
    /// writes inside `publish_with`).
    pub transfer: Option<Summary>,
    /// Minor page faults per frame in the publisher while writing and sending.
    pub publisher_faults_per_frame: f64,
    /// Minor page faults per frame in the subscriber while waiting and receiving.
    pub subscriber_faults_per_frame: f64,
}

/// Every transport in one mode.
#[derive(Debug, Clone, PartialEq)]
pub struct ModeResult {
    /// The mode.
    pub mode: WaitMode,
    /// One per transport, in [`Transport::ALL`] order.
    pub transports: Vec<TransportResult>,
}

impl ModeResult {
    /// The result of `transport`.
    pub fn get(&self, transport: Transport) -> Option<&TransportResult> {
        self.transports.iter().find(|t| t.transport == transport)
    }

    /// `p50(numerator) / p50(denominator)` of the totals.
    pub fn ratio_p50(&self, numerator: Transport, denominator: Transport) -> Option<f64> {
        let n = self.get(numerator)?.total.p50_ns as f64;
        let d = self.get(denominator)?.total.p50_ns as f64;
        (d > 0.0).then(|| n / d)
    }

    /// The same ratio for the transfer only.
    pub fn transfer_ratio_p50(&self, numerator: Transport, denominator: Transport) -> Option<f64> {
        let n = self.get(numerator)?.transfer?.p50_ns as f64;
        let d = self.get(denominator)?.transfer?.p50_ns as f64;
        (d > 0.0).then(|| n / d)
    }
}

/// The whole measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraResult {
    /// Image bytes per frame.
    pub image_bytes: usize,
    /// The sizes used.
    pub config: CameraConfig,
    /// Polling, then sleeping.
    pub modes: Vec<ModeResult>,
    /// The iceoryx2 service used (unique per run).
    pub service: String,
}

impl CameraResult {
    /// The result of `mode`.
    pub fn mode(&self, mode: WaitMode) -> Option<&ModeResult> {
        self.modes.iter().find(|m| m.mode == mode)
    }
}

/// The image pattern of frame `seq` (cheap to compute, different every frame, so nothing can
/// be skipped), written into `dst`.
pub fn render(dst: &mut [MaybeUninit<u8>], seq: u64) {
    let offset = seq as u8;
    for (i, byte) in dst.iter_mut().enumerate() {
        byte.write((i as u8).wrapping_add(offset));
    }
}

fn render_bytes(dst: &mut [u8], seq: u64) {
    // SAFETY: same length and layout; `render` only writes initialised bytes, so the slice
    // stays initialised.
    let dst = unsafe { &mut *(dst as *mut [u8] as *mut [MaybeUninit<u8>]) };
    render(dst, seq);
}

fn frame_header(seq: u64, start_ns: u64) -> CameraFrameHeader {
    let camera = world::camera::OverheadCamera {
        width_px: WIDTH_PX,
        height_px: HEIGHT_PX,
        metres_per_px: 0.00625,
        left_x_m: 0.0,
        top_y_m: 3.0,
    };
    CameraFrameHeader::for_layout(seq, start_ns, &world::camera::FrameLayout::rgb8(camera))
}

fn header_bytes(h: &CameraFrameHeader) -> [u8; HEADER_BYTES] {
    let mut out = [0u8; HEADER_BYTES];
    let parts: [&[u8]; 9] = [
        &h.frame_id.to_le_bytes(),
        &h.stamp_ns.to_le_bytes(),
        &h.width_px.to_le_bytes(),
        &h.height_px.to_le_bytes(),
        &h.pixel_format.to_le_bytes(),
        &h.row_stride_bytes.to_le_bytes(),
        &h.metres_per_px.to_le_bytes(),
        &h.left_x_m.to_le_bytes(),
        &h.top_y_m.to_le_bytes(),
    ];
    let mut at = 0;
    for part in parts {
        out[at..at + part.len()].copy_from_slice(part);
        at += part.len();
    }
    out
}

fn times_bytes(t: &FrameTimes) -> [u8; TIMES_BYTES] {
    let mut out = [0u8; TIMES_BYTES];
    out[..8].copy_from_slice(&t.seq.to_le_bytes());
    out[8..16].copy_from_slice(&t.start_ns.to_le_bytes());
    out[16..].copy_from_slice(&t.written_ns.to_le_bytes());
    out
}

fn times_from(bytes: &[u8]) -> FrameTimes {
    let word = |i: usize| {
        let mut w = [0u8; 8];
        if let Some(src) = bytes.get(i * 8..i * 8 + 8) {
            w.copy_from_slice(src);
        }
        u64::from_le_bytes(w)
    };
    FrameTimes {
        seq: word(0),
        start_ns: word(1),
        written_ns: word(2),
    }
}

/// The iceoryx2 service of the raw path: one publisher, one subscriber, nothing buffered
/// beyond one frame, so the publisher owns 3 samples of 3.5 MiB.
pub(crate) fn open_service(
    node: &Node<Ipc>,
    service: &str,
) -> Result<(FrameService, WakeService), BenchError> {
    let name = ServiceName::new(service).map_err(|e| BenchError::setup("service name")(&e))?;
    let frames = node
        .service_builder(&name)
        .publish_subscribe::<CameraFrameMsg>()
        .user_header::<FrameTimes>()
        .max_publishers(1)
        .max_subscribers(1)
        .max_nodes(2)
        .history_size(0)
        .subscriber_max_buffer_size(1)
        .subscriber_max_borrowed_samples(1)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| BenchError::setup(format!("opening iceoryx2 service {service}"))(&e))?;
    let wake_name = ServiceName::new(&format!("{service}/wake"))
        .map_err(|e| BenchError::setup("wake service name")(&e))?;
    let wake = node
        .service_builder(&wake_name)
        .event()
        .max_notifiers(1)
        .max_listeners(1)
        .max_nodes(2)
        .open_or_create()
        .map_err(|e| {
            BenchError::setup(format!("opening iceoryx2 event service {service}/wake"))(&e)
        })?;
    Ok((frames, wake))
}

fn new_node() -> Result<Node<Ipc>, BenchError> {
    NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Ipc>()
        .map_err(|e| BenchError::setup("creating the iceoryx2 node")(&e))
}

/// Removes the socket file when dropped.
struct SocketFile(PathBuf);

impl Drop for SocketFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// Runs the measurement against a peer started from `peer_exe`.
#[allow(
    clippy::too_many_lines,
    reason = "one benchmark: setup, the measured loop, the statistics"
)]
pub fn measure(peer_exe: &Path, config: &CameraConfig) -> Result<CameraResult, BenchError> {
    let service = names::unique("cam");
    let namespace = names::unique("ipc");
    let socket = SocketFile(std::env::temp_dir().join(format!("{}.sock", names::unique("uds"))));

    let node = new_node()?;
    let (frames, wake) = open_service(&node, &service)?;
    let subscriber = frames
        .subscriber_builder()
        .buffer_size(1)
        .create()
        .map_err(|e| BenchError::setup("creating the iceoryx2 subscriber")(&e))?;
    let listener = wake
        .listener_builder()
        .create()
        .map_err(|e| BenchError::setup("creating the iceoryx2 listener")(&e))?;
    // SAFETY: the descriptor belongs to `listener`, which lives in `reader` for the whole
    // measurement; it is only polled, never closed or read through this copy.
    let listener_fd = unsafe { listener.file_descriptor().native_handle() };
    let ipc_node = IpcNode::new(&namespace, "latency-sub")
        .map_err(|e| BenchError::setup("creating the grop-ipc node")(&e))?;
    let ipc_subscriber = ipc_node
        .subscriber::<CameraFrameMsg>()
        .map_err(|e| BenchError::setup("creating the grop-ipc subscriber")(&e))?;
    let uds = UnixListener::bind(&socket.0)
        .map_err(BenchError::io(format!("binding {}", socket.0.display())))?;
    let tcp = TcpListener::bind("127.0.0.1:0").map_err(BenchError::io("binding 127.0.0.1:0"))?;
    let tcp_port = tcp
        .local_addr()
        .map_err(BenchError::io("reading the TCP port"))?
        .port();

    let args = vec![
        "camera".to_owned(),
        "--service".to_owned(),
        service.clone(),
        "--namespace".to_owned(),
        namespace.clone(),
        "--uds".to_owned(),
        socket.0.display().to_string(),
        "--tcp-port".to_owned(),
        tcp_port.to_string(),
        "--gap-us".to_owned(),
        config.gap.as_micros().to_string(),
    ];
    let (mut peer, _) = Peer::spawn(peer_exe, &args)?;
    // The peer connected both sockets before it said ready: the connections are queued.
    let (mut uds_stream, _) = uds
        .accept()
        .map_err(BenchError::io("accepting the Unix socket"))?;
    let (mut tcp_stream, _) = tcp
        .accept()
        .map_err(BenchError::io("accepting the TCP socket"))?;
    tcp_stream
        .set_nodelay(true)
        .map_err(BenchError::io("TCP_NODELAY"))?;

    let mut reader = Reader {
        subscriber,
        listener,
        listener_fd,
        ipc_subscriber,
        uds: &mut uds_stream,
        tcp: &mut tcp_stream,
        buffer: vec![1u8; STREAM_FRAME_BYTES],
        seq: 0,
    };

    let mut modes = Vec::new();
    for mode in [WaitMode::Polling, WaitMode::Sleeping] {
        reader.set_mode(mode)?;
        let mut cold = [(0u64, 0u64); Transport::ALL.len()];
        for (index, transport) in Transport::ALL.into_iter().enumerate() {
            for k in 0..config.warmup_frames {
                let before = ThreadUsage::now();
                let sample = reader.frame(&mut peer, transport, mode)?;
                cold[index].1 += ThreadUsage::now().since(&before).minor_faults;
                if k == 0 {
                    cold[index].0 = sample.held_ns.saturating_sub(sample.start_ns);
                }
            }
        }
        // The peer prints its warm-up fault counts and starts counting anew.
        peer.send(b"w")?;
        let warm_line = peer.expect("warmup", Duration::from_secs(5))?;
        let mut totals: [Vec<u64>; Transport::ALL.len()] = Default::default();
        let mut transfers: [Vec<u64>; Transport::ALL.len()] = Default::default();
        let mut faults = [0u64; Transport::ALL.len()];
        for round in 0..config.rounds {
            for k in 0..Transport::ALL.len() {
                let index = (round + k) % Transport::ALL.len();
                let transport = Transport::ALL[index];
                for _ in 0..config.frames_per_round {
                    let before = ThreadUsage::now();
                    let sample = reader.frame(&mut peer, transport, mode)?;
                    faults[index] += ThreadUsage::now().since(&before).minor_faults;
                    totals[index].push(sample.held_ns.saturating_sub(sample.start_ns));
                    if let Some(written) = sample.written_ns {
                        transfers[index].push(sample.held_ns.saturating_sub(written));
                    }
                }
            }
        }
        peer.send(b"p")?;
        let line = peer.expect("faults", Duration::from_secs(5))?;
        let frames = (config.rounds * config.frames_per_round).max(1) as f64;
        let mut transports = Vec::new();
        for (index, transport) in Transport::ALL.into_iter().enumerate() {
            let code = char::from(transport.command(mode)).to_string();
            let publisher_faults: u64 = field(&line, &code)?;
            transports.push(TransportResult {
                transport,
                warmup: Warmup {
                    frames: config.warmup_frames,
                    first_frame_ns: cold[index].0,
                    publisher_faults: field(&warm_line, &code)?,
                    subscriber_faults: cold[index].1,
                },
                total: Summary::of(&mut totals[index]),
                transfer: (!transfers[index].is_empty())
                    .then(|| Summary::of(&mut transfers[index])),
                publisher_faults_per_frame: publisher_faults as f64 / frames,
                subscriber_faults_per_frame: faults[index] as f64 / frames,
            });
        }
        modes.push(ModeResult { mode, transports });
    }
    peer.send(b"q")?;
    peer.finish_ok(Duration::from_secs(10))?;
    Ok(CameraResult {
        image_bytes: IMAGE_BYTES,
        config: *config,
        modes,
        service,
    })
}

/// One received frame's stamps.
struct Stamps {
    start_ns: u64,
    written_ns: Option<u64>,
    held_ns: u64,
}

/// The subscriber side of every transport.
struct Reader<'a> {
    subscriber: Subscriber<Ipc, CameraFrameMsg, FrameTimes>,
    listener: Listener<Ipc>,
    listener_fd: i32,
    ipc_subscriber: grop_ipc::TopicSubscriber<CameraFrameMsg>,
    uds: &'a mut UnixStream,
    tcp: &'a mut TcpStream,
    buffer: Vec<u8>,
    seq: u64,
}

impl Reader<'_> {
    fn set_mode(&mut self, mode: WaitMode) -> Result<(), BenchError> {
        let nonblocking = mode == WaitMode::Polling;
        self.uds
            .set_nonblocking(nonblocking)
            .and_then(|()| self.tcp.set_nonblocking(nonblocking))
            .and_then(|()| self.uds.set_read_timeout(Some(FRAME_TIMEOUT)))
            .and_then(|()| self.tcp.set_read_timeout(Some(FRAME_TIMEOUT)))
            .map_err(BenchError::io("setting the socket mode"))
    }

    /// Asks the peer for one frame on `transport` and waits for it as `mode` says.
    #[allow(
        clippy::too_many_lines,
        reason = "one benchmark row: the same steps for each way of writing a frame"
    )]
    fn frame(
        &mut self,
        peer: &mut Peer,
        transport: Transport,
        mode: WaitMode,
    ) -> Result<Stamps, BenchError> {
        self.seq += 1;
        peer.send(&[transport.command(mode)])?;
        let deadline = Instant::now() + FRAME_TIMEOUT;
        let timeout = || BenchError::Timeout {
            what: format!("camera frame {} over {transport:?} ({mode:?})", self.seq),
            after: FRAME_TIMEOUT,
        };
        match transport {
            Transport::Iceoryx2 => loop {
                if mode == WaitMode::Sleeping {
                    self.listener
                        .try_wait(|_| {})
                        .map_err(|e| BenchError::setup("iceoryx2 listener")(&e))?;
                }
                let mut spins = 0u32;
                let sample = loop {
                    let received = self
                        .subscriber
                        .receive()
                        .map_err(|e| BenchError::setup("iceoryx2 receive")(&e))?;
                    if let Some(sample) = received {
                        break Some(sample);
                    }
                    if mode == WaitMode::Sleeping {
                        break None;
                    }
                    spins = spins.wrapping_add(1);
                    if spins % 4096 == 0 && Instant::now() > deadline {
                        return Err(timeout());
                    }
                    std::hint::spin_loop();
                };
                let held_ns = now_ns();
                match sample {
                    Some(sample) => {
                        let times = *sample.user_header();
                        drop(sample);
                        if times.seq == self.seq {
                            return Ok(Stamps {
                                start_ns: times.start_ns,
                                written_ns: Some(times.written_ns),
                                held_ns,
                            });
                        }
                        // An older frame (cannot happen with one in flight): keep waiting.
                    }
                    None => {
                        let left = deadline.saturating_duration_since(Instant::now());
                        if left.is_zero() {
                            return Err(timeout());
                        }
                        grop_clock::wait_readable(&[self.listener_fd], left)
                            .map_err(BenchError::io("waiting on the iceoryx2 listener"))?;
                    }
                }
            },
            Transport::GropIpc | Transport::GropIpcFrame => loop {
                let received = match mode {
                    WaitMode::Polling => {
                        let mut spins = 0u32;
                        loop {
                            let r = self
                                .ipc_subscriber
                                .try_recv()
                                .map_err(|e| BenchError::setup("grop-ipc receive")(&e))?;
                            if r.is_some() {
                                break r;
                            }
                            spins = spins.wrapping_add(1);
                            if spins % 4096 == 0 && Instant::now() > deadline {
                                return Err(timeout());
                            }
                            std::hint::spin_loop();
                        }
                    }
                    WaitMode::Sleeping => self
                        .ipc_subscriber
                        .recv_timeout(deadline.saturating_duration_since(Instant::now()))
                        .map_err(|e| BenchError::setup("grop-ipc receive")(&e))?,
                };
                let held_ns = now_ns();
                let Some(message) = received else {
                    return Err(timeout());
                };
                let (seq, start_ns) = (message.header.frame_id, message.header.stamp_ns);
                drop(message);
                if mode == WaitMode::Polling {
                    // The publisher notified too: clear the wake-up so they do not pile up.
                    let _ = self.ipc_subscriber.recv_timeout(Duration::ZERO);
                }
                if seq == self.seq {
                    return Ok(Stamps {
                        start_ns,
                        written_ns: None,
                        held_ns,
                    });
                }
            },
            Transport::UnixSocket | Transport::Tcp => {
                let stream: &mut dyn Read = match transport {
                    Transport::UnixSocket => &mut *self.uds,
                    _ => &mut *self.tcp,
                };
                let held_ns =
                    read_frame(stream, &mut self.buffer, mode, deadline).map_err(|e| {
                        match e.kind() {
                            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut => {
                                timeout()
                            }
                            _ => BenchError::io(format!("reading a frame over {transport:?}"))(e),
                        }
                    })?;
                let times = times_from(&self.buffer);
                if times.seq != self.seq {
                    return Err(BenchError::Peer(format!(
                        "frame {} arrived over {transport:?} when {} was expected",
                        times.seq, self.seq
                    )));
                }
                Ok(Stamps {
                    start_ns: times.start_ns,
                    written_ns: Some(times.written_ns),
                    held_ns,
                })
            }
        }
    }
}

/// Reads one whole frame; returns when the last byte is in. Polling: spins on a
/// non-blocking socket; sleeping: blocking reads.
fn read_frame(
    stream: &mut dyn Read,
    buffer: &mut [u8],
    mode: WaitMode,
    deadline: Instant,
) -> std::io::Result<u64> {
    let mut filled = 0;
    let mut spins = 0u32;
    while filled < buffer.len() {
        match stream.read(&mut buffer[filled..]) {
            Ok(0) => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock && mode == WaitMode::Polling => {
                spins = spins.wrapping_add(1);
                if spins % 4096 == 0 && Instant::now() > deadline {
                    return Err(std::io::ErrorKind::TimedOut.into());
                }
                std::hint::spin_loop();
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(now_ns())
}

/// What the peer's `camera` mode needs.
#[derive(Debug, Clone)]
pub struct PublisherArgs {
    /// iceoryx2 service.
    pub service: String,
    /// grop-ipc namespace.
    pub namespace: String,
    /// Unix socket to connect to.
    pub uds: PathBuf,
    /// TCP port on 127.0.0.1 to connect to.
    pub tcp_port: u16,
    /// Pause between a command and its frame.
    pub gap: Duration,
}

/// The peer side: publishes one frame per command byte read from stdin (`i`/`I`: iceoryx2
/// without/with the wake-up, `g`: grop-ipc, `u`: Unix socket, `t`: TCP; `w`: reset the fault
/// counters after printing them as the warm-up's, `p`: print them, `q` or end of input:
/// stop).
pub fn run_publisher(args: &PublisherArgs) -> Result<(), BenchError> {
    let node = new_node()?;
    let (frames, wake) = open_service(&node, &args.service)?;
    let publisher = frames
        .publisher_builder()
        .max_loaned_samples(1)
        .create()
        .map_err(|e| BenchError::setup("creating the iceoryx2 publisher")(&e))?;
    let notifier = wake
        .notifier_builder()
        .create()
        .map_err(|e| BenchError::setup("creating the iceoryx2 notifier")(&e))?;
    let ipc_node = IpcNode::new(&args.namespace, "latency-pub")
        .map_err(|e| BenchError::setup("creating the grop-ipc node")(&e))?;
    let ipc_publisher = ipc_node
        .publisher::<CameraFrameMsg>()
        .map_err(|e| BenchError::setup("creating the grop-ipc publisher")(&e))?;
    let mut uds = UnixStream::connect(&args.uds).map_err(BenchError::io(format!(
        "connecting to {}",
        args.uds.display()
    )))?;
    let mut tcp = TcpStream::connect(("127.0.0.1", args.tcp_port))
        .map_err(BenchError::io("connecting to the TCP port"))?;
    tcp.set_nodelay(true)
        .map_err(BenchError::io("TCP_NODELAY"))?;
    // Touched once here, so that writing a frame into it never faults.
    let mut buffer = vec![1u8; STREAM_FRAME_BYTES];
    println!("ready");

    let codes = *b"iIgfut";
    let mut faults = [0u64; 6];
    let mut stdin = std::io::stdin().lock();
    let mut command = [0u8; 1];
    let mut seq = 0u64;
    loop {
        match stdin.read(&mut command) {
            Ok(0) => break,
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(BenchError::io("reading commands")(e)),
        }
        let code = command[0];
        match code {
            b'q' => break,
            b'w' | b'p' => {
                let mut line = String::from(if code == b'w' { "warmup" } else { "faults" });
                for (c, n) in codes.iter().zip(faults) {
                    line.push_str(&format!(" {}={n}", char::from(*c)));
                }
                println!("{line}");
                faults = [0; 6];
                continue;
            }
            _ => {}
        }
        let Some(slot) = codes.iter().position(|c| *c == code) else {
            return Err(BenchError::Peer(format!("unknown command byte {code}")));
        };
        seq += 1;
        std::thread::sleep(args.gap);
        let before = ThreadUsage::now();
        match code {
            b'i' | b'I' => {
                publish_frame(&publisher, seq)?;
                if code == b'I' {
                    notifier
                        .notify()
                        .map_err(|e| BenchError::setup("iceoryx2 notify")(&e))?;
                }
            }
            b'g' => {
                let start = now_ns();
                ipc_publisher
                    .publish_with(|frame| {
                        if let Ok(image) = frame.image_mut(frame_header(seq, start)) {
                            render_bytes(image, seq);
                        }
                    })
                    .map_err(|e| BenchError::setup("grop-ipc publish")(&e))?;
            }
            b'f' => {
                let start = now_ns();
                ipc_publisher
                    .publish_frame(frame_header(seq, start), |image| render_bytes(image, seq))
                    .map_err(|e| BenchError::setup("grop-ipc publish_frame")(&e))?;
            }
            b'u' => publish_stream(&mut uds, &mut buffer, seq)
                .map_err(BenchError::io("writing to the Unix socket"))?,
            _ => publish_stream(&mut tcp, &mut buffer, seq)
                .map_err(BenchError::io("writing to the TCP socket"))?,
        }
        faults[slot] += ThreadUsage::now().since(&before).minor_faults;
    }
    Ok(())
}

pub(crate) fn publish_frame(
    publisher: &Publisher<Ipc, CameraFrameMsg, FrameTimes>,
    seq: u64,
) -> Result<(), BenchError> {
    let start_ns = now_ns();
    let mut sample = publisher
        .loan_uninit()
        .map_err(|e| BenchError::setup("iceoryx2 loan")(&e))?;
    let frame = sample.payload_mut().as_mut_ptr();
    // SAFETY: `frame` points to the loaned slot for one CameraFrameMsg in shared memory,
    // aligned and exclusively ours until sent. Only raw field pointers are formed (no reference
    // to the whole, possibly never-written message); the pixel slice covers the first
    // IMAGE_BYTES of the 3.5 MiB array, inside the slot.
    let pixels = unsafe {
        std::ptr::addr_of_mut!((*frame).header).write(frame_header(seq, start_ns));
        let first = std::ptr::addr_of_mut!((*frame).pixels).cast::<MaybeUninit<u8>>();
        std::slice::from_raw_parts_mut(first, IMAGE_BYTES)
    };
    render(pixels, seq);
    let written_ns = now_ns();
    *sample.user_header_mut() = FrameTimes {
        seq,
        start_ns,
        written_ns,
    };
    // SAFETY: the header and the image are written above. The rest of the pixel array is
    // memory of a shared-memory file that the OS zero-filled when the segment was created and
    // that only ever holds bytes of earlier frames: initialised bytes, valid for u8 (the
    // subscriber reads only the header and the image).
    let sample = unsafe { sample.assume_init() };
    sample
        .send()
        .map_err(|e| BenchError::setup("iceoryx2 send")(&e))?;
    Ok(())
}

fn publish_stream(stream: &mut impl Write, buffer: &mut [u8], seq: u64) -> std::io::Result<()> {
    let start_ns = now_ns();
    render_bytes(&mut buffer[TIMES_BYTES + HEADER_BYTES..], seq);
    buffer[TIMES_BYTES..TIMES_BYTES + HEADER_BYTES]
        .copy_from_slice(&header_bytes(&frame_header(seq, start_ns)));
    let written_ns = now_ns();
    buffer[..TIMES_BYTES].copy_from_slice(&times_bytes(&FrameTimes {
        seq,
        start_ns,
        written_ns,
    }));
    stream.write_all(buffer)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn socket_frame_layout() {
        assert_eq!(IMAGE_BYTES, 921_600);
        assert_eq!(std::mem::size_of::<CameraFrameHeader>(), HEADER_BYTES);
        let t = FrameTimes {
            seq: 3,
            start_ns: 4,
            written_ns: 5,
        };
        assert_eq!(times_from(&times_bytes(&t)), t);
        assert_eq!(times_from(&[]), FrameTimes::default());
        let h = header_bytes(&frame_header(9, 10));
        assert_eq!(h[..8], 9u64.to_le_bytes());
        let mut image = vec![0u8; 300];
        render_bytes(&mut image, 1);
        assert_eq!((image[0], image[255], image[256]), (1, 0, 1));
    }
}
