//! The live view: a WebSocket server speaking the Foxglove WebSocket protocol
//! ([`protocol::SUBPROTOCOL`]), so that the Foxglove app watches a mission while it runs. It is
//! fed by the recorder: every channel the mission log has is advertised with the log's topic,
//! encoding and schema, and each message the recorder takes is also offered here.
//!
//! Never in the way:
//! - the recorder offers through a queue bounded in bytes ([`LiveConfig::queue_bytes`]) that
//!   never waits: a full queue drops the message and counts it;
//! - one thread of its own (the hub) takes from that queue and writes to every client over
//!   non-blocking sockets; a client whose socket is full loses messages (counted) until it reads
//!   again, so a slow or stalled client slows nothing else; another thread accepts connections;
//! - a viewer, never a commander: it claims no capability but `time` (when it publishes the
//!   simulated clock), and a client's `advertise`, published message, service call or parameter
//!   request is refused with an error status and counted.
//!
//! New subscribers get the newest message of their channel at once (a plan is published once,
//! and a viewer that connects later still sees it).

pub mod protocol;

use std::collections::{BTreeMap, VecDeque};
use std::io::ErrorKind;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tungstenite::http::{HeaderValue, StatusCode};
use tungstenite::protocol::WebSocketConfig;
use tungstenite::{Message, WebSocket};

use super::codec::Channel;
use protocol::{ClientRequest, Level};

/// Most clients at once; more are turned away with an error status.
pub const MAX_CLIENTS: usize = 8;
/// Requests read from one client per pass of the hub.
const REQUESTS_PER_PASS: usize = 64;
/// The simulated time is published at most this often (simulated ns).
const TIME_PERIOD_NS: u64 = 50_000_000;

/// Settings of the live view.
#[derive(Debug, Clone)]
pub struct LiveConfig {
    /// Where to listen (port 0: one the OS chooses; [`LiveServer::local_addr`] says which).
    pub addr: SocketAddr,
    /// Most bytes of messages waiting between the recorder and the hub.
    pub queue_bytes: usize,
    /// Most bytes a client's connection buffers in user space before its messages are dropped.
    pub client_buffer_bytes: usize,
    /// Publish the recorder's clock as the server's time (`time` capability): on a simulated
    /// clock.
    pub publish_time: bool,
    /// The server's name in `serverInfo`.
    pub name: String,
}

impl LiveConfig {
    /// A viewer on `addr` with a 16 MiB queue and 8 MiB per client.
    pub fn new(addr: SocketAddr) -> Self {
        Self {
            addr,
            queue_bytes: 16 << 20,
            client_buffer_bytes: 8 << 20,
            publish_time: false,
            name: "grop".into(),
        }
    }
}

/// What went wrong starting the live view.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The address could not be bound.
    #[error("live view: cannot listen on {addr}: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The error.
        source: std::io::Error,
    },
    /// A thread could not start.
    #[error("live view: starting its {what} thread: {source}")]
    Thread {
        /// Which thread.
        what: &'static str,
        /// The error.
        source: std::io::Error,
    },
}

/// Counts of a live view, reported when it closes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LiveSummary {
    /// Connections that completed the handshake.
    pub clients: u64,
    /// Messages (and time updates) written to clients.
    pub sent: u64,
    /// Messages the recorder offered that the full queue dropped.
    pub queue_dropped: u64,
    /// Messages (and time updates) a client did not get because its connection was full.
    pub client_dropped: u64,
    /// Client requests refused (publishing, services, parameters, ...).
    pub refused: u64,
    /// Client messages that were not the protocol.
    pub invalid: u64,
}

impl std::fmt::Display for LiveSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "live_clients={} live_sent={} live_queue_dropped={} live_client_dropped={} live_refused={} live_invalid={}",
            self.clients,
            self.sent,
            self.queue_dropped,
            self.client_dropped,
            self.refused,
            self.invalid
        )
    }
}

#[derive(Default)]
struct Counters {
    clients: AtomicU64,
    sent: AtomicU64,
    queue_dropped: AtomicU64,
    client_dropped: AtomicU64,
    refused: AtomicU64,
    invalid: AtomicU64,
}

impl Counters {
    fn add(c: &AtomicU64, n: u64) {
        c.fetch_add(n, Ordering::Relaxed);
    }

    fn summary(&self) -> LiveSummary {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        LiveSummary {
            clients: g(&self.clients),
            sent: g(&self.sent),
            queue_dropped: g(&self.queue_dropped),
            client_dropped: g(&self.client_dropped),
            refused: g(&self.refused),
            invalid: g(&self.invalid),
        }
    }
}

enum Item {
    Message {
        channel: Channel,
        log_time: u64,
        data: Arc<[u8]>,
    },
    Time(u64),
}

#[derive(Default)]
struct QueueState {
    items: VecDeque<Item>,
    bytes: usize,
    closed: bool,
}

struct Shared {
    queue: Mutex<QueueState>,
    filled: Condvar,
    counters: Counters,
    stop: AtomicBool,
}

fn lock(m: &Mutex<QueueState>) -> MutexGuard<'_, QueueState> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The recorder's end of the live view: offers never wait (a full queue drops and counts).
pub struct LiveFeed {
    shared: Arc<Shared>,
    queue_bytes: usize,
    publish_time: bool,
    last_time: Option<u64>,
}

impl LiveFeed {
    /// Offers one message (copied); `false` when the queue was full and it was dropped.
    pub fn offer(&mut self, channel: Channel, log_time: u64, data: &[u8]) -> bool {
        let len = data.len().max(1);
        let mut q = lock(&self.shared.queue);
        if q.closed || (q.bytes + len > self.queue_bytes && !q.items.is_empty()) {
            drop(q);
            Counters::add(&self.shared.counters.queue_dropped, 1);
            return false;
        }
        q.bytes += len;
        q.items.push_back(Item::Message {
            channel,
            log_time,
            data: Arc::from(data),
        });
        drop(q);
        self.shared.filled.notify_one();
        true
    }

    /// Offers the clock's time (when the server publishes time), at most every 50 ms of it.
    pub fn offer_time(&mut self, now_ns: u64) {
        if !self.publish_time
            || self
                .last_time
                .is_some_and(|t| now_ns.saturating_sub(t) < TIME_PERIOD_NS)
        {
            return;
        }
        self.last_time = Some(now_ns);
        let mut q = lock(&self.shared.queue);
        if q.closed {
            return;
        }
        // Time is 9 bytes: always room for it.
        q.bytes += 9;
        q.items.push_back(Item::Time(now_ns));
        drop(q);
        self.shared.filled.notify_one();
    }
}

/// A running live view (see the module docs).
pub struct LiveServer {
    shared: Arc<Shared>,
    addr: SocketAddr,
    config: LiveConfig,
    hub: Option<JoinHandle<()>>,
    acceptor: Option<JoinHandle<()>>,
}

impl LiveServer {
    /// Binds `config.addr` and starts the acceptor and hub threads.
    pub fn start(config: LiveConfig) -> Result<Self, LiveError> {
        let bind = |source| LiveError::Bind {
            addr: config.addr,
            source,
        };
        let listener = TcpListener::bind(config.addr).map_err(bind)?;
        listener.set_nonblocking(true).map_err(bind)?;
        let addr = listener.local_addr().map_err(bind)?;
        let shared = Arc::new(Shared {
            queue: Mutex::new(QueueState::default()),
            filled: Condvar::new(),
            counters: Counters::default(),
            stop: AtomicBool::new(false),
        });
        let (tx, rx) = channel();
        let acceptor = {
            let shared = Arc::clone(&shared);
            let ws_config = WebSocketConfig::default()
                .max_write_buffer_size(config.client_buffer_bytes.max(1 << 20))
                .max_message_size(Some(1 << 20))
                .max_frame_size(Some(1 << 20));
            std::thread::Builder::new()
                .name("live-accept".into())
                .spawn(move || accept_loop(&listener, &shared, ws_config, &tx))
                .map_err(|source| LiveError::Thread {
                    what: "accept",
                    source,
                })?
        };
        let hub = {
            let shared = Arc::clone(&shared);
            let info = protocol::server_info(
                &config.name,
                config.publish_time,
                &format!("{}-{}", std::process::id(), addr.port()),
            );
            std::thread::Builder::new()
                .name("live-hub".into())
                .spawn(move || hub_loop(&shared, &rx, &info))
                .map_err(|source| LiveError::Thread {
                    what: "hub",
                    source,
                })?
        };
        Ok(Self {
            shared,
            addr,
            config,
            hub: Some(hub),
            acceptor: Some(acceptor),
        })
    }

    /// The address it listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The recorder's end (one per server; more share the queue and its bound).
    pub fn feed(&self) -> LiveFeed {
        LiveFeed {
            shared: Arc::clone(&self.shared),
            queue_bytes: self.config.queue_bytes.max(1),
            publish_time: self.config.publish_time,
            last_time: None,
        }
    }

    /// The counts so far.
    pub fn summary(&self) -> LiveSummary {
        self.shared.counters.summary()
    }

    /// Sends what is queued, closes every connection and stops the threads.
    pub fn finish(mut self) -> LiveSummary {
        self.close();
        self.shared.counters.summary()
    }

    fn close(&mut self) {
        lock(&self.shared.queue).closed = true;
        self.shared.stop.store(true, Ordering::Relaxed);
        self.shared.filled.notify_all();
        for t in [self.acceptor.take(), self.hub.take()]
            .into_iter()
            .flatten()
        {
            if t.join().is_err() {
                log::error!("live view: a thread panicked");
            }
        }
    }
}

impl Drop for LiveServer {
    fn drop(&mut self) {
        self.close();
    }
}

fn accept_loop(
    listener: &TcpListener,
    shared: &Shared,
    config: WebSocketConfig,
    tx: &Sender<(WebSocket<TcpStream>, SocketAddr)>,
) {
    while !shared.stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((stream, peer)) => match handshake(stream, config) {
                Ok(ws) => {
                    log::info!("live view: {peer} connected");
                    Counters::add(&shared.counters.clients, 1);
                    if tx.send((ws, peer)).is_err() {
                        return;
                    }
                }
                Err(e) => log::warn!("live view: {peer}: handshake failed: {e}"),
            },
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(e) => {
                log::warn!("live view: accepting a connection: {e}");
                std::thread::sleep(Duration::from_millis(20));
            }
        }
    }
}

/// The WebSocket handshake, blocking for at most 2 s, which must name the subprotocol; the
/// socket is non-blocking afterwards.
fn handshake(stream: TcpStream, config: WebSocketConfig) -> Result<WebSocket<TcpStream>, String> {
    let io = |e: std::io::Error| e.to_string();
    stream.set_nonblocking(false).map_err(io)?;
    stream
        .set_read_timeout(Some(Duration::from_secs(2)))
        .map_err(io)?;
    stream
        .set_write_timeout(Some(Duration::from_secs(2)))
        .map_err(io)?;
    let _ = stream.set_nodelay(true);
    // The callback's type is tungstenite's (its error is an HTTP response).
    #[allow(clippy::result_large_err)]
    let callback = |req: &Request, mut resp: Response| -> Result<Response, ErrorResponse> {
        let offered = req
            .headers()
            .get_all("Sec-WebSocket-Protocol")
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(','))
            .any(|p| p.trim() == protocol::SUBPROTOCOL);
        if !offered {
            let mut e = ErrorResponse::new(Some(format!(
                "this server speaks the {} subprotocol only",
                protocol::SUBPROTOCOL
            )));
            *e.status_mut() = StatusCode::BAD_REQUEST;
            return Err(e);
        }
        resp.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            HeaderValue::from_static(protocol::SUBPROTOCOL),
        );
        Ok(resp)
    };
    let ws = tungstenite::accept_hdr_with_config(stream, callback, Some(config))
        .map_err(|e| e.to_string())?;
    ws.get_ref().set_nonblocking(true).map_err(io)?;
    Ok(ws)
}

struct Client {
    ws: WebSocket<TcpStream>,
    peer: SocketAddr,
    /// Subscription id -> channel.
    subs: BTreeMap<u32, Channel>,
    /// The last write or flush could not finish: the socket is full.
    blocked: bool,
    alive: bool,
}

fn would_block(e: &tungstenite::Error) -> bool {
    matches!(e, tungstenite::Error::Io(io) if io.kind() == ErrorKind::WouldBlock)
}

impl Client {
    /// Writes `msg` unless the connection is still full (then it is dropped and counted).
    fn send(&mut self, msg: Message, counters: &Counters) {
        if !self.alive {
            return;
        }
        if self.blocked {
            match self.ws.flush() {
                Ok(()) => self.blocked = false,
                Err(e) if would_block(&e) => {
                    Counters::add(&counters.client_dropped, 1);
                    return;
                }
                Err(_) => {
                    self.alive = false;
                    return;
                }
            }
        }
        match self.ws.write(msg) {
            // Written, or buffered behind a full socket: it goes out with the next flush.
            Ok(()) => Counters::add(&counters.sent, 1),
            Err(e) if would_block(&e) => {
                Counters::add(&counters.sent, 1);
                self.blocked = true;
            }
            Err(tungstenite::Error::WriteBufferFull(_)) => {
                Counters::add(&counters.client_dropped, 1);
                self.blocked = true;
            }
            Err(_) => self.alive = false,
        }
    }

    fn flush(&mut self) {
        if !self.alive {
            return;
        }
        match self.ws.flush() {
            Ok(()) => self.blocked = false,
            Err(e) if would_block(&e) => self.blocked = true,
            Err(_) => self.alive = false,
        }
    }

    fn status(&mut self, level: Level, text: &str, counters: &Counters) {
        self.send(Message::text(protocol::status(level, text)), counters);
    }

    /// Reads and answers what the client sent (at most [`REQUESTS_PER_PASS`] requests, so that
    /// a client that floods requests does not keep the others waiting).
    fn serve(&mut self, cache: &BTreeMap<Channel, (u64, Arc<[u8]>)>, counters: &Counters) {
        for _ in 0..REQUESTS_PER_PASS {
            if !self.alive {
                break;
            }
            let request = match self.ws.read() {
                Ok(Message::Text(t)) => protocol::parse_text(t.as_str()),
                Ok(Message::Binary(b)) => protocol::parse_binary(&b),
                Ok(Message::Close(_)) => {
                    self.alive = false;
                    break;
                }
                Ok(_) => continue,
                Err(e) if would_block(&e) => break,
                Err(_) => {
                    self.alive = false;
                    break;
                }
            };
            match request {
                ClientRequest::Subscribe(list) => {
                    for s in list {
                        let Some(channel) = protocol::channel_of(s.channel_id) else {
                            self.status(
                                Level::Error,
                                &format!("subscribe: no channel {}", s.channel_id),
                                counters,
                            );
                            continue;
                        };
                        self.subs.insert(s.id, channel);
                        if let Some((log_time, data)) = cache.get(&channel) {
                            let m = protocol::message_data(s.id, *log_time, data);
                            self.send(Message::binary(m), counters);
                        }
                    }
                }
                ClientRequest::Unsubscribe(ids) => {
                    for id in ids {
                        self.subs.remove(&id);
                    }
                }
                ClientRequest::Refused(what) => {
                    Counters::add(&counters.refused, 1);
                    log::warn!("live view: {}: refused {what}", self.peer);
                    self.status(
                        Level::Error,
                        &format!(
                            "refused: {what}. This server is a viewer: no client publishing, services or parameters"
                        ),
                        counters,
                    );
                }
                ClientRequest::Invalid(why) => {
                    Counters::add(&counters.invalid, 1);
                    self.status(Level::Warning, &format!("ignored: {why}"), counters);
                }
            }
        }
    }
}

fn hub_loop(shared: &Shared, incoming: &Receiver<(WebSocket<TcpStream>, SocketAddr)>, info: &str) {
    let counters = &shared.counters;
    let advertise = protocol::advertise(&Channel::ALL);
    let mut clients: Vec<Client> = Vec::new();
    let mut cache: BTreeMap<Channel, (u64, Arc<[u8]>)> = BTreeMap::new();
    let mut items: Vec<Item> = Vec::new();
    loop {
        let closed = {
            let mut q = lock(&shared.queue);
            if q.items.is_empty() && !q.closed {
                // Wake at least every 10 ms to read the clients.
                q = shared
                    .filled
                    .wait_timeout(q, Duration::from_millis(10))
                    .map(|(g, _)| g)
                    .unwrap_or_else(|e| e.into_inner().0);
            }
            items.extend(q.items.drain(..));
            q.bytes = 0;
            q.closed
        };
        while let Ok((ws, peer)) = incoming.try_recv() {
            let mut c = Client {
                ws,
                peer,
                subs: BTreeMap::new(),
                blocked: false,
                alive: true,
            };
            if clients.len() >= MAX_CLIENTS {
                c.status(
                    Level::Error,
                    &format!("the live view serves {MAX_CLIENTS} clients at most"),
                    counters,
                );
                c.flush();
                continue;
            }
            c.send(Message::text(info.to_owned()), counters);
            c.send(Message::text(advertise.clone()), counters);
            clients.push(c);
        }
        for item in items.drain(..) {
            match item {
                Item::Message {
                    channel,
                    log_time,
                    data,
                } => {
                    for c in &mut clients {
                        let ids: Vec<u32> = c
                            .subs
                            .iter()
                            .filter(|(_, ch)| **ch == channel)
                            .map(|(id, _)| *id)
                            .collect();
                        for id in ids {
                            let m = protocol::message_data(id, log_time, &data);
                            c.send(Message::binary(m), counters);
                        }
                    }
                    cache.insert(channel, (log_time, data));
                }
                Item::Time(ns) => {
                    for c in &mut clients {
                        c.send(Message::binary(protocol::time(ns)), counters);
                    }
                }
            }
        }
        for c in &mut clients {
            c.serve(&cache, counters);
            c.flush();
        }
        clients.retain(|c| {
            if !c.alive {
                log::info!("live view: {} left", c.peer);
            }
            c.alive
        });
        if closed {
            for c in &mut clients {
                let _ = c.ws.close(None);
                c.flush();
            }
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;
    use tungstenite::client::IntoClientRequest;

    type Ws = WebSocket<TcpStream>;

    fn start(publish_time: bool) -> LiveServer {
        LiveServer::start(LiveConfig {
            publish_time,
            ..LiveConfig::new("127.0.0.1:0".parse().expect("address"))
        })
        .expect("the live view starts")
    }

    fn connect(addr: SocketAddr, subprotocol: Option<&str>) -> Result<Ws, String> {
        let stream = TcpStream::connect(addr).map_err(|e| e.to_string())?;
        stream
            .set_read_timeout(Some(Duration::from_secs(10)))
            .map_err(|e| e.to_string())?;
        let mut request = format!("ws://{addr}/")
            .into_client_request()
            .map_err(|e| e.to_string())?;
        if let Some(p) = subprotocol {
            request.headers_mut().insert(
                "Sec-WebSocket-Protocol",
                HeaderValue::from_str(p).map_err(|e| e.to_string())?,
            );
        }
        tungstenite::client(request, stream)
            .map(|(ws, _)| ws)
            .map_err(|e| e.to_string())
    }

    fn text(ws: &mut Ws) -> Value {
        loop {
            if let Message::Text(t) = ws.read().expect("a message") {
                return serde_json::from_str(t.as_str()).expect("JSON");
            }
        }
    }

    fn binary(ws: &mut Ws) -> Vec<u8> {
        loop {
            if let Message::Binary(b) = ws.read().expect("a message") {
                return b.to_vec();
            }
        }
    }

    /// Waits until the server has read everything sent before: it answers requests in order,
    /// and this one with a warning.
    fn sync(ws: &mut Ws) {
        ws.send(Message::text(r#"{"op":"sync"}"#)).expect("sends");
        loop {
            let v = text(ws);
            if v["op"] == "status" && v["level"] == 1 {
                return;
            }
        }
    }

    fn subscribe(ws: &mut Ws, id: u32, channel: Channel) {
        let msg = serde_json::json!({"op": "subscribe", "subscriptions": [
            {"id": id, "channelId": protocol::channel_id(channel)}]});
        ws.send(Message::text(msg.to_string())).expect("subscribe");
    }

    #[test]
    fn a_taken_address_is_named_in_the_error() {
        let taken = TcpListener::bind("127.0.0.1:0").expect("bind");
        let addr = taken.local_addr().expect("address");
        let e = LiveServer::start(LiveConfig::new(addr))
            .err()
            .expect("the address is taken");
        assert!(e.to_string().contains(&addr.to_string()), "{e}");
    }

    #[test]
    fn a_client_without_the_subprotocol_is_turned_away() {
        let server = start(false);
        assert!(connect(server.local_addr(), None).is_err());
        assert!(connect(server.local_addr(), Some("something.else")).is_err());
        assert_eq!(server.finish().clients, 0);
    }

    #[test]
    fn a_subscriber_gets_the_newest_message_at_once_then_each_new_one_and_the_time() {
        let server = start(true);
        let mut feed = server.feed();
        // Before anyone connects: kept as the newest of its channel.
        assert!(feed.offer(Channel::TaskPlan, 5, b"{\"plan\":1}"));
        let mut ws = connect(server.local_addr(), Some(protocol::SUBPROTOCOL)).expect("connects");
        let info = text(&mut ws);
        assert_eq!(info["op"], "serverInfo");
        assert_eq!(info["capabilities"], serde_json::json!(["time"]));
        assert_eq!(text(&mut ws)["op"], "advertise");
        subscribe(&mut ws, 42, Channel::TaskPlan);
        assert_eq!(
            binary(&mut ws),
            protocol::message_data(42, 5, b"{\"plan\":1}")
        );
        // Not subscribed: not sent.
        assert!(feed.offer(Channel::Can, 6, b"{\"can\":1}"));
        assert!(feed.offer(Channel::TaskPlan, 7, b"{\"plan\":2}"));
        assert_eq!(
            binary(&mut ws),
            protocol::message_data(42, 7, b"{\"plan\":2}")
        );
        feed.offer_time(1_000_000_000);
        feed.offer_time(1_010_000_000); // within 50 ms: not published
        feed.offer_time(1_050_000_000);
        assert_eq!(binary(&mut ws), protocol::time(1_000_000_000));
        assert_eq!(binary(&mut ws), protocol::time(1_050_000_000));
        // Unsubscribed: nothing more of it; the next binary message is the time.
        ws.send(Message::text(
            r#"{"op":"unsubscribe","subscriptionIds":[42]}"#,
        ))
        .expect("unsubscribe");
        sync(&mut ws);
        assert!(feed.offer(Channel::TaskPlan, 8, b"{\"plan\":3}"));
        feed.offer_time(2_000_000_000);
        assert_eq!(binary(&mut ws), protocol::time(2_000_000_000));
        let s = server.finish();
        assert_eq!(s.clients, 1);
        assert_eq!(s.refused, 0);
        assert_eq!(s.invalid, 1);
    }

    #[test]
    fn publishing_and_service_calls_are_refused_and_counted() {
        let server = start(false);
        let mut ws = connect(server.local_addr(), Some(protocol::SUBPROTOCOL)).expect("connects");
        assert_eq!(text(&mut ws)["capabilities"], serde_json::json!([]));
        assert_eq!(text(&mut ws)["op"], "advertise");
        let requests = [
            Message::text(
                r#"{"op":"advertise","channels":[{"id":1,"topic":"/cmd","encoding":"json","schemaName":"x"}]}"#,
            ),
            Message::binary(vec![1, 1, 0, 0, 0, b'{', b'}']),
            Message::binary(vec![2, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]),
            Message::text(r#"{"op":"setParameters","parameters":[]}"#),
        ];
        for r in requests {
            ws.send(r).expect("sends");
            let status = text(&mut ws);
            assert_eq!(status["op"], "status");
            assert_eq!(status["level"], 2);
            assert!(
                status["message"]
                    .as_str()
                    .is_some_and(|m| m.contains("refused")),
                "{status}"
            );
        }
        ws.send(Message::text("not json")).expect("sends");
        assert_eq!(text(&mut ws)["level"], 1);
        let s = server.finish();
        assert_eq!(s.refused, 4);
        assert_eq!(s.invalid, 1);
    }

    #[test]
    fn a_stalled_client_loses_messages_and_the_feed_never_waits() {
        let server = start(false);
        let mut feed = server.feed();
        let mut ws = connect(server.local_addr(), Some(protocol::SUBPROTOCOL)).expect("connects");
        assert_eq!(text(&mut ws)["op"], "serverInfo");
        assert_eq!(text(&mut ws)["op"], "advertise");
        subscribe(&mut ws, 1, Channel::CameraFrame);
        sync(&mut ws);
        // 256 MiB to a client that never reads: far more than any socket buffers.
        let frame = vec![b'x'; 1 << 20];
        let mut offered = 0;
        for i in 0..256u64 {
            offered += u64::from(feed.offer(Channel::CameraFrame, i, &frame));
        }
        let s = server.finish();
        assert!(s.client_dropped > 0, "{s:?}");
        // serverInfo, advertise and the warning, then the frames.
        assert_eq!(
            s.client_dropped + s.sent + s.queue_dropped,
            3 + 256,
            "{s:?}"
        );
        assert_eq!(offered + s.queue_dropped, 256);
        drop(ws);
    }
}
