//! The RTDE client: protocol 2 negotiation, recipes, start/pause, newest-package-wins receive.
//!
//! Synchronous by design: the arm's cyclic executive calls [`RtdeClient::receive_latest`] once
//! per cycle and the controller's 500 Hz stream is its clock. Buffers are allocated when the
//! client and its recipes are set up; the steady-state receive and send paths reuse them.

use std::io;
use std::net::{SocketAddr, ToSocketAddrs};
use std::time::{Duration, Instant};

use thiserror::Error;

use crate::transport::{TcpTransport, Transport};

use super::wire::{
    self, ControllerVersion, FrameError, HEADER_LEN, PackageType, RtdeType, RtdeValue, SetupField,
    TextLevel, TextMessage, ValueDecodeError,
};

/// Default RTDE port of a UR controller.
pub const RTDE_PORT: u16 = 30004;

/// Receive buffer size: two maximum-size packages, so a full one always fits after compaction.
const RX_BUF_LEN: usize = 2 * (u16::MAX as usize + 1);

/// Timeouts of an RTDE connection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RtdeTimeouts {
    /// TCP connect.
    pub connect: Duration,
    /// Wait for the reply to a setup request.
    pub reply: Duration,
    /// Write of one package.
    pub write: Duration,
}

impl Default for RtdeTimeouts {
    fn default() -> Self {
        Self {
            connect: Duration::from_secs(2),
            reply: Duration::from_secs(2),
            write: Duration::from_millis(500),
        }
    }
}

/// When and how [`RtdeClient::reconnect`] retries.
///
/// Attempt 1 starts at once; before attempt `k > 1` the client sleeps
/// `min(first_backoff * 2^(k-2), max_backoff)`. Each attempt is bounded by the client's
/// [`RtdeTimeouts`] (connect, then one reply per setup request).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RtdeReconnectPolicy {
    /// Attempts in all (0 is taken as 1).
    pub attempts: u32,
    /// Sleep before the second attempt.
    pub first_backoff: Duration,
    /// Longest sleep between two attempts.
    pub max_backoff: Duration,
}

impl Default for RtdeReconnectPolicy {
    /// 5 attempts, 100 ms doubling to at most 1 s: about 2.5 s of backoff in all, the time a
    /// controller's RTDE server takes to come back after a restart of its program.
    fn default() -> Self {
        Self {
            attempts: 5,
            first_backoff: Duration::from_millis(100),
            max_backoff: Duration::from_secs(1),
        }
    }
}

/// A package the client took off the stream and dropped because it was malformed. Counted
/// ([`RtdeClient::malformed_packages`]) and kept as [`RtdeClient::last_malformed`]; receiving
/// goes on with the next package.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum RtdeMalformed {
    /// A size field below the 3-byte header: the framing was lost, and `skipped` bytes were
    /// dropped to reach the next plausible header ([`wire::resync_offset`]).
    #[error("size field {size} below the 3-byte header; {skipped} bytes dropped to resynchronise")]
    BadSize {
        /// The size field as received.
        size: u16,
        /// Bytes dropped.
        skipped: usize,
    },
    /// A type letter RTDE does not define.
    #[error("unknown package type {type_byte:#04x} with {len} payload bytes")]
    UnknownType {
        /// The type byte.
        type_byte: u8,
        /// Its payload length.
        len: usize,
    },
    /// A data package without even a recipe id.
    #[error("empty data package")]
    EmptyData,
    /// A data package for another recipe than the output recipe.
    #[error("data package for recipe {got}, the output recipe is {expected}")]
    WrongRecipe {
        /// The recipe id in the package.
        got: u8,
        /// The output recipe's id.
        expected: u8,
    },
    /// A data package whose fields do not match the output recipe (too short or too long).
    #[error("data package does not match output recipe {recipe_id}: {source}")]
    DataMismatch {
        /// The output recipe id.
        recipe_id: u8,
        /// What did not match.
        source: ValueDecodeError,
    },
    /// A text message whose lengths run past its payload.
    #[error("undecodable text message of {len} payload bytes")]
    BadText {
        /// Payload length.
        len: usize,
    },
}

/// Errors that end an RTDE connection or a request on it.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RtdeLinkError {
    /// The socket failed (reset, refused, ...).
    #[error("RTDE connection to {addr}: {source}")]
    Io {
        /// Controller address.
        addr: SocketAddr,
        /// The underlying error.
        source: io::Error,
    },
    /// The controller closed the connection.
    #[error("RTDE connection to {addr} closed by the controller")]
    Closed {
        /// Controller address.
        addr: SocketAddr,
    },
    /// No (matching) package arrived in time.
    #[error("RTDE {what} from {addr}: no answer within {waited:?}")]
    Timeout {
        /// Controller address.
        addr: SocketAddr,
        /// What was awaited.
        what: &'static str,
        /// How long.
        waited: Duration,
    },
    /// The byte stream cannot be framed any more.
    #[error("RTDE stream from {addr} is corrupt: {source}")]
    Frame {
        /// Controller address.
        addr: SocketAddr,
        /// Framing error.
        source: FrameError,
    },
}

/// Errors of [`RtdeClient::connect`].
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RtdeConnectError {
    /// The address did not resolve.
    #[error("cannot resolve RTDE address: {0}")]
    Resolve(io::Error),
    /// TCP connect or the version request failed.
    #[error(transparent)]
    Link(#[from] RtdeLinkError),
    /// The controller refused protocol version 2.
    #[error("controller at {addr} refused RTDE protocol version {version}")]
    VersionRefused {
        /// Controller address.
        addr: SocketAddr,
        /// Version asked for.
        version: u16,
    },
    /// The reply to `V` was malformed.
    #[error("malformed reply to the protocol version request: {len} bytes")]
    BadVersionReply {
        /// Payload length.
        len: usize,
    },
}

/// Errors of a simple request (`v`, `S`, `P`).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RtdeRequestError {
    /// Link failure.
    #[error(transparent)]
    Link(#[from] RtdeLinkError),
    /// The controller answered 0 (not accepted).
    #[error("controller refused RTDE request {request:?}")]
    Refused {
        /// The request.
        request: PackageType,
    },
    /// The reply payload had the wrong length.
    #[error("malformed reply to {request:?}: {len} bytes")]
    BadReply {
        /// The request.
        request: PackageType,
        /// Payload length.
        len: usize,
    },
    /// Request not allowed in the current state (e.g. start without an output recipe).
    #[error("RTDE request {request:?} not allowed: {reason}")]
    NotAllowed {
        /// The request.
        request: PackageType,
        /// Why.
        reason: &'static str,
    },
}

/// Errors of recipe setup (`O`, `I`).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RtdeSetupError {
    /// Link failure.
    #[error(transparent)]
    Link(#[from] RtdeLinkError),
    /// Empty name list, or a list longer than 2048 bytes.
    #[error("RTDE variable list invalid: {reason}")]
    BadList {
        /// Why.
        reason: &'static str,
    },
    /// The controller does not know these names.
    #[error("controller does not know RTDE variables {names:?}")]
    NotFound {
        /// The unknown names.
        names: Vec<String>,
    },
    /// Another client or a fieldbus controls these inputs.
    #[error("RTDE inputs {names:?} are in use by another client or a fieldbus")]
    InUse {
        /// The names in use.
        names: Vec<String>,
    },
    /// The reply cannot be parsed or does not match the request.
    #[error("malformed RTDE setup reply: {reason}")]
    BadReply {
        /// Why.
        reason: String,
    },
    /// Setup is only allowed while paused.
    #[error("RTDE recipes can only be set up while the stream is paused")]
    WhileStarted,
}

/// Errors of [`RtdeClient::receive_latest`].
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RtdeReceiveError {
    /// Link failure, including no data within the timeout.
    #[error(transparent)]
    Link(#[from] RtdeLinkError),
    /// No output recipe is set up, or the stream is not started.
    #[error("RTDE receive without a started output recipe")]
    NotStarted,
    /// No valid data package before the deadline, but malformed packages came (each was
    /// dropped; the next receive starts after them).
    #[error(
        "no valid RTDE data package before the deadline; {count} malformed packages dropped, the last: {last}"
    )]
    Malformed {
        /// Malformed packages during this receive.
        count: u64,
        /// The last of them.
        last: RtdeMalformed,
    },
}

/// Why one attempt of [`RtdeClient::reconnect`] failed.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RtdeReconnectCause {
    /// TCP connect or the protocol version request failed.
    #[error(transparent)]
    Connect(#[from] RtdeConnectError),
    /// Re-sending a recipe setup failed.
    #[error("re-sending the RTDE recipe setup: {0}")]
    Setup(#[from] RtdeSetupError),
    /// Restarting the output stream failed.
    #[error("restarting the RTDE stream: {0}")]
    Start(#[from] RtdeRequestError),
    /// The controller answered a re-sent recipe with other types (or, for inputs, another
    /// id) than before, so values and recipes the caller holds would be wrong.
    #[error("the controller answered the re-sent {recipe} recipe with other ids or types")]
    RecipeChanged {
        /// `"output"` or `"input"`.
        recipe: &'static str,
    },
}

/// Errors of [`RtdeClient::reconnect`].
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RtdeReconnectError {
    /// Every attempt failed; the client is as it was before the call (link down).
    #[error("RTDE reconnect to {addr} gave up after {attempts} attempts; last: {last}")]
    GaveUp {
        /// Controller address.
        addr: SocketAddr,
        /// Attempts made.
        attempts: u32,
        /// Why the last attempt failed.
        last: RtdeReconnectCause,
    },
}

/// Errors of [`RtdeClient::send_inputs`].
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RtdeSendError {
    /// Link failure.
    #[error(transparent)]
    Link(#[from] RtdeLinkError),
    /// The values do not match the recipe.
    #[error("values do not match input recipe {recipe_id}: {source}")]
    BadValues {
        /// The input recipe id.
        recipe_id: u8,
        /// Mismatch.
        source: ValueDecodeError,
    },
    /// The recipe does not belong to this connection.
    #[error("input recipe {recipe_id} was not set up on this connection")]
    UnknownRecipe {
        /// The recipe id.
        recipe_id: u8,
    },
}

/// The output recipe: names in request order and the types the controller returned.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputRecipe {
    /// Recipe id from the `O` reply.
    pub id: u8,
    /// Output frequency asked for.
    pub frequency_hz: f64,
    /// Variable names, in order.
    pub names: Vec<String>,
    /// Types as returned by the controller (the decoding uses these, not a local table).
    pub types: Vec<RtdeType>,
}

impl OutputRecipe {
    /// Position of a variable in the recipe.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Bytes of one data package's fields (without header and recipe id).
    pub fn data_len(&self) -> usize {
        self.types.iter().map(|t| t.wire_len()).sum()
    }
}

/// An input recipe set up on this connection.
#[derive(Debug, Clone, PartialEq)]
pub struct InputRecipe {
    /// Recipe id from the `I` reply.
    pub id: u8,
    /// Variable names, in order.
    pub names: Vec<String>,
    /// Types as returned by the controller.
    pub types: Vec<RtdeType>,
}

/// The newest data package, decoded by the output recipe's types.
#[derive(Debug, Clone, PartialEq)]
pub struct DataPackage {
    /// Values in recipe order.
    pub values: Vec<RtdeValue>,
    /// Packages received since the last call and dropped because a newer one arrived.
    pub skipped: u32,
    /// When the package was taken off the socket (local monotonic clock).
    pub received_at: Instant,
    /// Count of data packages received on this connection, this one included.
    pub sequence: u64,
}

impl DataPackage {
    /// An empty package shaped for `recipe` (allocate once, reuse every cycle).
    pub fn for_recipe(recipe: &OutputRecipe) -> Self {
        Self {
            values: recipe.types.iter().map(|&t| RtdeValue::zero(t)).collect(),
            skipped: 0,
            received_at: Instant::now(),
            sequence: 0,
        }
    }
}

/// Connection state (mirrors the controller's per-connection state machine).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RtdeState {
    /// Connected, protocol negotiated, not streaming.
    Paused,
    /// Output stream started.
    Started,
}

/// An RTDE (port 30004) client speaking protocol version 2, over TCP unless built on another
/// [`Transport`] with [`RtdeClient::over`].
#[derive(Debug)]
pub struct RtdeClient<T = TcpTransport> {
    stream: T,
    addr: SocketAddr,
    timeouts: RtdeTimeouts,
    rx: Box<[u8]>,
    rx_start: usize,
    rx_end: usize,
    tx: Vec<u8>,
    state: RtdeState,
    output: Option<OutputRecipe>,
    inputs: Vec<InputRecipe>,
    data_packages: u64,
    text_messages: u64,
    malformed: u64,
    last_malformed: Option<RtdeMalformed>,
    reconnects: u64,
}

impl RtdeClient<TcpTransport> {
    /// Connects to `addr`, negotiates protocol version 2 and returns a paused client.
    pub fn connect(
        addr: impl ToSocketAddrs,
        timeouts: RtdeTimeouts,
    ) -> Result<Self, RtdeConnectError> {
        let addr = addr
            .to_socket_addrs()
            .map_err(RtdeConnectError::Resolve)?
            .next()
            .ok_or_else(|| {
                RtdeConnectError::Resolve(io::Error::new(io::ErrorKind::NotFound, "no address"))
            })?;
        let stream = TcpTransport::connect(addr, timeouts.connect, timeouts.write)
            .map_err(|source| RtdeLinkError::Io { addr, source })?;
        Self::over(stream, timeouts)
    }
}

impl<T: Transport> RtdeClient<T> {
    /// Negotiates protocol version 2 over an open `stream` and returns a paused client;
    /// `timeouts.reply` bounds every reply (the others are the transport's business).
    pub fn over(stream: T, timeouts: RtdeTimeouts) -> Result<Self, RtdeConnectError> {
        let addr = stream.peer();
        let mut client = Self {
            stream,
            addr,
            timeouts,
            rx: vec![0u8; RX_BUF_LEN].into_boxed_slice(),
            rx_start: 0,
            rx_end: 0,
            tx: Vec::with_capacity(4096),
            state: RtdeState::Paused,
            output: None,
            inputs: Vec::new(),
            data_packages: 0,
            text_messages: 0,
            malformed: 0,
            last_malformed: None,
            reconnects: 0,
        };
        client.negotiate()?;
        Ok(client)
    }

    /// Asks for protocol version 2 (`V`).
    fn negotiate(&mut self) -> Result<(), RtdeConnectError> {
        let reply = self.request(
            PackageType::RequestProtocolVersion,
            &wire::PROTOCOL_VERSION.to_be_bytes(),
            "protocol version reply",
        )?;
        match reply.as_slice() {
            [1] => Ok(()),
            [0] => Err(RtdeConnectError::VersionRefused {
                addr: self.addr,
                version: wire::PROTOCOL_VERSION,
            }),
            other => Err(RtdeConnectError::BadVersionReply { len: other.len() }),
        }
    }

    /// Reconnects after a lost link, under `policy`, and restores the session: a new TCP
    /// connection, protocol 2, the output recipe and every input recipe re-sent in their
    /// original order (same names, same frequency), and `S` if the stream was started.
    ///
    /// The old socket is shut down first; bytes still buffered from it are dropped. Recipes
    /// the caller holds stay valid: the controller numbers input recipes per connection in
    /// request order, so re-sending them in order gives the same ids, and an answer with other
    /// ids or types fails the attempt ([`RtdeReconnectCause::RecipeChanged`]). Data package
    /// sequence numbers continue across the reconnect. Blocks for up to `attempts` x (the
    /// connect timeout + a reply timeout per request) plus the backoffs: call it with the
    /// arm stopped, never from a control cycle. When every attempt fails the client is left
    /// as before the call (same recipes and state, link down), so it can be called again.
    pub fn reconnect(&mut self, policy: &RtdeReconnectPolicy) -> Result<(), RtdeReconnectError> {
        self.stream.shutdown();
        let attempts = policy.attempts.max(1);
        let mut backoff = policy.first_backoff;
        let mut attempt = 1;
        loop {
            match self.restore_session() {
                Ok(()) => {
                    self.reconnects += 1;
                    log::info!("RTDE reconnected to {} (attempt {attempt})", self.addr);
                    return Ok(());
                }
                Err(last) if attempt >= attempts => {
                    return Err(RtdeReconnectError::GaveUp {
                        addr: self.addr,
                        attempts,
                        last,
                    });
                }
                Err(e) => {
                    log::warn!(
                        "RTDE reconnect to {} attempt {attempt}/{attempts}: {e}",
                        self.addr
                    );
                }
            }
            std::thread::sleep(backoff);
            backoff = backoff.saturating_mul(2).min(policy.max_backoff);
            attempt += 1;
        }
    }

    /// Number of successful [`Self::reconnect`] calls.
    pub fn reconnects(&self) -> u64 {
        self.reconnects
    }

    /// One reconnect attempt; on failure the recipes and state are put back as they were.
    fn restore_session(&mut self) -> Result<(), RtdeReconnectCause> {
        let (output, inputs, state) = (self.output.clone(), self.inputs.clone(), self.state);
        let result = self.replay_session(output.as_ref(), &inputs, state);
        if result.is_err() {
            self.output = output;
            self.inputs = inputs;
            self.state = state;
        }
        result
    }

    fn replay_session(
        &mut self,
        output: Option<&OutputRecipe>,
        inputs: &[InputRecipe],
        state: RtdeState,
    ) -> Result<(), RtdeReconnectCause> {
        let addr = self.addr;
        self.stream
            .reopen()
            .map_err(|source| RtdeConnectError::from(RtdeLinkError::Io { addr, source }))?;
        self.rx_start = 0;
        self.rx_end = 0;
        self.state = RtdeState::Paused;
        self.negotiate()?;
        if let Some(old) = output {
            let names: Vec<&str> = old.names.iter().map(String::as_str).collect();
            if self.setup_outputs(&names, old.frequency_hz)?.types != old.types {
                return Err(RtdeReconnectCause::RecipeChanged { recipe: "output" });
            }
        }
        self.inputs.clear();
        for old in inputs {
            let names: Vec<&str> = old.names.iter().map(String::as_str).collect();
            let new = self.setup_inputs(&names)?;
            if new.id != old.id || new.types != old.types {
                return Err(RtdeReconnectCause::RecipeChanged { recipe: "input" });
            }
        }
        if state == RtdeState::Started {
            self.start()?;
        }
        Ok(())
    }

    /// The controller's address.
    pub fn peer(&self) -> SocketAddr {
        self.addr
    }

    /// Current stream state.
    pub fn state(&self) -> RtdeState {
        self.state
    }

    /// The output recipe, once set up.
    pub fn output_recipe(&self) -> Option<&OutputRecipe> {
        self.output.as_ref()
    }

    /// Number of text messages received (each is also logged).
    pub fn text_messages(&self) -> u64 {
        self.text_messages
    }

    /// Number of malformed packages taken off the stream and dropped on this client (over
    /// reconnects).
    pub fn malformed_packages(&self) -> u64 {
        self.malformed
    }

    /// The most recent malformed package, if any.
    pub fn last_malformed(&self) -> Option<RtdeMalformed> {
        self.last_malformed
    }

    /// Asks the controller for its version (`v`).
    pub fn controller_version(&mut self) -> Result<ControllerVersion, RtdeRequestError> {
        let payload = self.request(PackageType::GetUrcontrolVersion, &[], "controller version")?;
        ControllerVersion::decode(&payload).ok_or(RtdeRequestError::BadReply {
            request: PackageType::GetUrcontrolVersion,
            len: payload.len(),
        })
    }

    /// Sets up the output recipe (`O`) with the frequency in Hz (up to 500 on e-Series).
    pub fn setup_outputs(
        &mut self,
        names: &[&str],
        frequency_hz: f64,
    ) -> Result<&OutputRecipe, RtdeSetupError> {
        if self.state == RtdeState::Started {
            return Err(RtdeSetupError::WhileStarted);
        }
        let list = Self::name_list(names)?;
        let mut payload = frequency_hz.to_be_bytes().to_vec();
        payload.extend_from_slice(list.as_bytes());
        let reply = self.request(PackageType::SetupOutputs, &payload, "output setup reply")?;
        let (id, types) = Self::parse_setup_reply(names, &reply, false)?;
        self.output = Some(OutputRecipe {
            id,
            frequency_hz,
            names: names.iter().map(|s| s.to_string()).collect(),
            types,
        });
        // Just set above.
        self.output
            .as_ref()
            .ok_or_else(|| RtdeSetupError::BadReply {
                reason: "output recipe lost".into(),
            })
    }

    /// Sets up an input recipe (`I`); its id is what later [`Self::send_inputs`] calls use.
    pub fn setup_inputs(&mut self, names: &[&str]) -> Result<InputRecipe, RtdeSetupError> {
        if self.state == RtdeState::Started {
            return Err(RtdeSetupError::WhileStarted);
        }
        let list = Self::name_list(names)?;
        let reply = self.request(
            PackageType::SetupInputs,
            list.as_bytes(),
            "input setup reply",
        )?;
        let (id, types) = Self::parse_setup_reply(names, &reply, true)?;
        let recipe = InputRecipe {
            id,
            names: names.iter().map(|s| s.to_string()).collect(),
            types,
        };
        self.inputs.push(recipe.clone());
        Ok(recipe)
    }

    fn name_list(names: &[&str]) -> Result<String, RtdeSetupError> {
        if names.is_empty() || names.iter().any(|n| n.is_empty() || n.contains(',')) {
            return Err(RtdeSetupError::BadList {
                reason: "names must be non-empty and contain no comma",
            });
        }
        let list = names.join(",");
        if list.len() > wire::MAX_VARIABLE_LIST_LEN {
            return Err(RtdeSetupError::BadList {
                reason: "list longer than 2048 bytes",
            });
        }
        Ok(list)
    }

    fn parse_setup_reply(
        names: &[&str],
        reply: &[u8],
        input: bool,
    ) -> Result<(u8, Vec<RtdeType>), RtdeSetupError> {
        let (&id, rest) = reply
            .split_first()
            .ok_or_else(|| RtdeSetupError::BadReply {
                reason: "empty reply".into(),
            })?;
        let text = std::str::from_utf8(rest).map_err(|_| RtdeSetupError::BadReply {
            reason: "type list is not ASCII".into(),
        })?;
        let words: Vec<&str> = wire::split_names(text).collect();
        if words.len() != names.len() {
            return Err(RtdeSetupError::BadReply {
                reason: format!("{} types for {} names: {text:?}", words.len(), names.len()),
            });
        }
        let mut types = Vec::with_capacity(words.len());
        let (mut not_found, mut in_use) = (Vec::new(), Vec::new());
        for (name, word) in names.iter().zip(words) {
            match SetupField::from_name(word) {
                Some(SetupField::Type(t)) => types.push(t),
                Some(SetupField::NotFound) => not_found.push(name.to_string()),
                Some(SetupField::InUse) => in_use.push(name.to_string()),
                None => {
                    return Err(RtdeSetupError::BadReply {
                        reason: format!("unknown type {word:?} for {name:?}"),
                    });
                }
            }
        }
        if !not_found.is_empty() {
            return Err(RtdeSetupError::NotFound { names: not_found });
        }
        if !in_use.is_empty() {
            return Err(RtdeSetupError::InUse { names: in_use });
        }
        // Recipe id 0 marks a refused recipe (G-RTDE); outputs keep whatever id they get.
        if input && id == 0 {
            return Err(RtdeSetupError::BadReply {
                reason: "input recipe id 0".into(),
            });
        }
        Ok((id, types))
    }

    /// Starts the output stream (`S`).
    pub fn start(&mut self) -> Result<(), RtdeRequestError> {
        if self.output.is_none() {
            return Err(RtdeRequestError::NotAllowed {
                request: PackageType::Start,
                reason: "no output recipe set up",
            });
        }
        self.accepted(PackageType::Start, "start reply")?;
        self.state = RtdeState::Started;
        Ok(())
    }

    /// Pauses the output stream (`P`); data packages still in flight are discarded.
    pub fn pause(&mut self) -> Result<(), RtdeRequestError> {
        self.accepted(PackageType::Pause, "pause reply")?;
        self.state = RtdeState::Paused;
        Ok(())
    }

    fn accepted(&mut self, ty: PackageType, what: &'static str) -> Result<(), RtdeRequestError> {
        let payload = self.request(ty, &[], what)?;
        match payload.as_slice() {
            [0] => Err(RtdeRequestError::Refused { request: ty }),
            [_] => Ok(()),
            other => Err(RtdeRequestError::BadReply {
                request: ty,
                len: other.len(),
            }),
        }
    }

    /// Sends one input data package (`U`) on `recipe`.
    pub fn send_inputs(
        &mut self,
        recipe: &InputRecipe,
        values: &[RtdeValue],
    ) -> Result<(), RtdeSendError> {
        if !self
            .inputs
            .iter()
            .any(|r| r.id == recipe.id && r.types == recipe.types)
        {
            return Err(RtdeSendError::UnknownRecipe {
                recipe_id: recipe.id,
            });
        }
        self.tx.clear();
        let start = 0;
        // Size patched below, once the payload length is known.
        self.tx
            .extend_from_slice(&[0, 0, PackageType::DataPackage as u8, recipe.id]);
        wire::encode_fields(&recipe.types, values, &mut self.tx).map_err(|source| {
            RtdeSendError::BadValues {
                recipe_id: recipe.id,
                source,
            }
        })?;
        wire::patch_size(&mut self.tx, start).map_err(|source| RtdeLinkError::Frame {
            addr: self.addr,
            source,
        })?;
        let addr = self.addr;
        self.stream
            .write_all(&self.tx)
            .map_err(|source| RtdeLinkError::Io { addr, source })?;
        Ok(())
    }

    /// Waits up to `timeout` for data and stores the **newest** data package in `out`.
    ///
    /// Every package already buffered in the socket is read, until the socket is empty or the
    /// deadline has passed (a controller that floods always has more; the call still returns
    /// by its deadline, with the newest package read so far); older data packages are counted
    /// in `out.skipped` and dropped, text messages are logged, malformed packages are dropped
    /// and counted ([`Self::malformed_packages`]). No data within `timeout` is a
    /// [`RtdeLinkError::Timeout`] (or [`RtdeReceiveError::Malformed`] when only malformed
    /// packages came): for a 500 Hz stream that means the controller or the link is gone, and
    /// the caller must stop the arm.
    pub fn receive_latest(
        &mut self,
        out: &mut DataPackage,
        timeout: Duration,
    ) -> Result<(), RtdeReceiveError> {
        if self.state != RtdeState::Started {
            return Err(RtdeReceiveError::NotStarted);
        }
        let deadline = Instant::now() + timeout;
        let malformed_before = self.malformed;
        let mut got = 0u32;
        loop {
            got = got.saturating_add(self.drain_buffered(out)?);
            if got > 0 {
                // Take whatever else the kernel already holds, without waiting and only until
                // the deadline.
                if Instant::now() < deadline && self.fill_nonblocking()? {
                    continue;
                }
                out.skipped = got - 1;
                return Ok(());
            }
            match self.fill(deadline, timeout, "data package") {
                Ok(()) => {}
                Err(RtdeLinkError::Timeout { .. }) if self.malformed > malformed_before => {
                    return Err(RtdeReceiveError::Malformed {
                        count: self.malformed - malformed_before,
                        last: self.last_malformed.unwrap_or(RtdeMalformed::EmptyData),
                    });
                }
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// Stores the newest data package in `out` if one has arrived, waiting at most `wait` (wall
    /// time) when none is buffered; `Ok(false)` when none came. For a cyclic executive that
    /// must not block for long, and for lock-step HIL, where the package of the cycle is
    /// already in the socket when the world's step returns (`wait` may then be zero).
    ///
    /// Silence is not an error here: the caller decides staleness on its own clock. Link
    /// failures (EOF, reset, corrupt stream) are errors as in [`Self::receive_latest`].
    pub fn receive_newest(
        &mut self,
        out: &mut DataPackage,
        wait: Duration,
    ) -> Result<bool, RtdeReceiveError> {
        if self.state != RtdeState::Started {
            return Err(RtdeReceiveError::NotStarted);
        }
        let deadline = Instant::now() + wait;
        let mut got = 0u32;
        let mut first_read = true;
        loop {
            got = got.saturating_add(self.drain_buffered(out)?);
            // Take whatever the kernel already holds, without waiting: one read always (so a
            // zero wait still sees the package that is there), more only until the deadline,
            // since a controller that floods always has more.
            let may_read = first_read || Instant::now() < deadline;
            first_read = false;
            if may_read && self.fill_nonblocking()? {
                continue;
            }
            if got > 0 {
                out.skipped = got - 1;
                return Ok(true);
            }
            if wait.is_zero() || Instant::now() >= deadline {
                return Ok(false);
            }
            match self.fill(deadline, wait, "data package") {
                Ok(()) => {}
                Err(RtdeLinkError::Timeout { .. }) => return Ok(false),
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// Decodes every complete package in the buffer; returns the number of data packages.
    /// Every package is consumed, whatever it holds: a malformed one is counted and dropped.
    fn drain_buffered(&mut self, out: &mut DataPackage) -> Result<u32, RtdeReceiveError> {
        let mut count = 0;
        while let Some((type_byte, start, end)) = self.next_package() {
            let recipe = self.output.as_ref().ok_or(RtdeReceiveError::NotStarted)?;
            let payload = &self.rx[start..end];
            let malformed = match PackageType::from_byte(type_byte) {
                Some(PackageType::DataPackage) => match Self::decode_data(recipe, payload, out) {
                    Ok(()) => {
                        self.data_packages += 1;
                        out.sequence = self.data_packages;
                        out.received_at = Instant::now();
                        count += 1;
                        None
                    }
                    Err(m) => Some(m),
                },
                Some(PackageType::TextMessage) => {
                    self.text_messages += 1;
                    Self::log_text(payload).err()
                }
                Some(other) => {
                    log::warn!("RTDE: unexpected package type {other:?} while streaming; ignored");
                    None
                }
                None => Some(RtdeMalformed::UnknownType {
                    type_byte,
                    len: payload.len(),
                }),
            };
            if let Some(m) = malformed {
                Self::note_malformed(self.addr, &mut self.malformed, &mut self.last_malformed, m);
            }
        }
        Ok(count)
    }

    /// Decodes a data package's payload into `out`, which is left alone unless it matches.
    fn decode_data(
        recipe: &OutputRecipe,
        payload: &[u8],
        out: &mut DataPackage,
    ) -> Result<(), RtdeMalformed> {
        let (&id, fields) = payload.split_first().ok_or(RtdeMalformed::EmptyData)?;
        if id != recipe.id {
            return Err(RtdeMalformed::WrongRecipe {
                got: id,
                expected: recipe.id,
            });
        }
        wire::decode_fields(&recipe.types, fields, &mut out.values).map_err(|source| {
            RtdeMalformed::DataMismatch {
                recipe_id: recipe.id,
                source,
            }
        })
    }

    /// Counts and records a dropped package. Logged for the 1st, 2nd, 4th, 8th ... one, so
    /// that a controller sending garbage cannot flood the log.
    fn note_malformed(
        addr: SocketAddr,
        count: &mut u64,
        last: &mut Option<RtdeMalformed>,
        m: RtdeMalformed,
    ) {
        *count += 1;
        *last = Some(m);
        if count.is_power_of_two() {
            log::warn!("RTDE from {addr}: dropped a malformed package ({m}); {count} so far");
        }
    }

    /// Frames the next package in the receive buffer and consumes it: returns its type byte
    /// and payload range (valid until the next read into the buffer), or `None` when more
    /// bytes are needed. A size field below the header is dropped up to the next plausible
    /// header, counted, and framing goes on, so a corrupt stretch never blocks later packages.
    fn next_package(&mut self) -> Option<(u8, usize, usize)> {
        loop {
            let buf = &self.rx[self.rx_start..self.rx_end];
            match wire::split_package(buf) {
                Ok(None) => return None,
                Ok(Some((pkg, used))) => {
                    let start = self.rx_start;
                    self.rx_start += used;
                    return Some((pkg.type_byte, start + HEADER_LEN, start + used));
                }
                Err(e) => {
                    let size = match e {
                        FrameError::SizeBelowHeader { size } => size,
                        _ => u16::from_be_bytes([buf[0], buf[1]]),
                    };
                    let skipped = wire::resync_offset(buf).max(1);
                    self.rx_start += skipped;
                    Self::note_malformed(
                        self.addr,
                        &mut self.malformed,
                        &mut self.last_malformed,
                        RtdeMalformed::BadSize { size, skipped },
                    );
                }
            }
        }
    }

    fn log_text(payload: &[u8]) -> Result<(), RtdeMalformed> {
        let m = TextMessage::decode(payload)
            .map_err(|_| RtdeMalformed::BadText { len: payload.len() })?;
        let level = match m.level {
            TextLevel::Exception | TextLevel::Error => log::Level::Error,
            TextLevel::Warning => log::Level::Warn,
            TextLevel::Info => log::Level::Info,
        };
        log::log!(level, "controller [{}]: {}", m.source, m.message);
        Ok(())
    }

    /// Sends a setup request and returns the payload of the reply of the same type.
    /// Text messages in between are logged; stale data packages are dropped.
    fn request(
        &mut self,
        ty: PackageType,
        payload: &[u8],
        what: &'static str,
    ) -> Result<Vec<u8>, RtdeLinkError> {
        self.tx.clear();
        wire::push_package(&mut self.tx, ty, payload).map_err(|source| RtdeLinkError::Frame {
            addr: self.addr,
            source,
        })?;
        let addr = self.addr;
        self.stream
            .write_all(&self.tx)
            .map_err(|source| RtdeLinkError::Io { addr, source })?;
        let deadline = Instant::now() + self.timeouts.reply;
        loop {
            while let Some((type_byte, start, end)) = self.next_package() {
                let payload = &self.rx[start..end];
                if type_byte == ty as u8 {
                    return Ok(payload.to_vec());
                }
                let malformed = match PackageType::from_byte(type_byte) {
                    Some(PackageType::TextMessage) => {
                        self.text_messages += 1;
                        Self::log_text(payload).err()
                    }
                    // Stale data packages and late replies to earlier requests.
                    Some(_) => None,
                    None => Some(RtdeMalformed::UnknownType {
                        type_byte,
                        len: payload.len(),
                    }),
                };
                if let Some(m) = malformed {
                    Self::note_malformed(addr, &mut self.malformed, &mut self.last_malformed, m);
                }
            }
            self.fill(deadline, self.timeouts.reply, what)?;
        }
    }

    /// Moves unread bytes to the buffer start so a full package always fits.
    fn compact(&mut self) {
        if self.rx_start > 0 {
            self.rx.copy_within(self.rx_start..self.rx_end, 0);
            self.rx_end -= self.rx_start;
            self.rx_start = 0;
        }
    }

    /// Blocking read until at least one byte arrived or the deadline passed; `waited` is the
    /// whole wait the caller allowed (for the error message).
    fn fill(
        &mut self,
        deadline: Instant,
        waited: Duration,
        what: &'static str,
    ) -> Result<(), RtdeLinkError> {
        self.compact();
        let addr = self.addr;
        loop {
            let now = Instant::now();
            let left = deadline.saturating_duration_since(now);
            if left.is_zero() {
                return Err(RtdeLinkError::Timeout { addr, what, waited });
            }
            self.stream
                .set_read_timeout(left)
                .map_err(|source| RtdeLinkError::Io { addr, source })?;
            match self.stream.read(&mut self.rx[self.rx_end..]) {
                Ok(0) => return Err(RtdeLinkError::Closed { addr }),
                Ok(n) => {
                    self.rx_end += n;
                    return Ok(());
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    return Err(RtdeLinkError::Timeout { addr, what, waited });
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(source) => return Err(RtdeLinkError::Io { addr, source }),
            }
        }
    }

    /// Reads whatever the kernel holds without blocking; true when bytes arrived.
    fn fill_nonblocking(&mut self) -> Result<bool, RtdeLinkError> {
        self.compact();
        let addr = self.addr;
        let io_err = |source| RtdeLinkError::Io { addr, source };
        self.stream.set_nonblocking(true).map_err(io_err)?;
        let result = loop {
            match self.stream.read(&mut self.rx[self.rx_end..]) {
                Ok(0) => break Err(RtdeLinkError::Closed { addr }),
                Ok(n) => {
                    self.rx_end += n;
                    break Ok(true);
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break Ok(false),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(source) => break Err(RtdeLinkError::Io { addr, source }),
            }
        };
        self.stream.set_nonblocking(false).map_err(io_err)?;
        result
    }

    /// Closes the connection (pausing first if started, as URPY does).
    pub fn disconnect(mut self) {
        if self.state == RtdeState::Started {
            let _ = self.pause();
        }
        self.stream.shutdown();
    }
}
