//! One connection (TCP, or any [`Transport`]) that carries one ASCII request line and one
//! reply line at a time (the dashboard server and the Robotiq URCap socket), with two guarantees
//! the clients build on:
//!
//! - **A deadline per reply, not per read.** The deadline is fixed when the request has been
//!   written, and every read waits only for what is left of it, so a server that dribbles a
//!   byte now and then cannot stretch a 200 ms reply timeout into seconds.
//! - **No stale replies.** Neither protocol numbers or echoes its requests, so a reply that
//!   comes after its deadline cannot be told from the answer to the next request. After a
//!   timeout (or a reply line over the length limit, whose tail would read as the next reply)
//!   the link is marked stale and the client opens a fresh connection before its next
//!   request; the old socket is shut down, so the late reply is never read. Draining the old
//!   socket instead would not do: the late reply may arrive only after the drain.
//!
//! The line buffer is allocated once; a request/reply round trip allocates nothing unless it
//! fails.

use std::io;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use crate::transport::Transport;

/// Longest reply line accepted, line break included (bytes).
pub const MAX_LINE_LEN: usize = 4096;

/// Why a reply line did not come.
#[derive(Debug)]
pub(crate) enum LineError {
    /// The peer closed the connection.
    Closed,
    /// No whole line before the deadline (the link is now stale).
    Timeout,
    /// A line longer than [`MAX_LINE_LEN`] (the link is now stale).
    TooLong,
    /// Socket failure, or a line that is not UTF-8 (`InvalidData`).
    Io(io::Error),
}

/// A request/reply line connection (see the module docs).
#[derive(Debug)]
pub(crate) struct LineLink<T> {
    transport: T,
    timeout: Duration,
    buf: Box<[u8]>,
    /// Bytes received and not yet consumed, from the buffer start.
    len: usize,
    /// Bytes of the line returned last, dropped before the next read.
    consumed: usize,
    stale: bool,
}

impl<T: Transport> LineLink<T> {
    /// A link over `transport` with `timeout` for every reply.
    pub(crate) fn new(transport: T, timeout: Duration) -> Self {
        Self {
            transport,
            timeout,
            buf: vec![0u8; MAX_LINE_LEN].into_boxed_slice(),
            len: 0,
            consumed: 0,
            stale: false,
        }
    }

    /// The peer, for errors and logs.
    pub(crate) fn peer(&self) -> SocketAddr {
        self.transport.peer()
    }

    /// The reply timeout.
    pub(crate) fn timeout(&self) -> Duration {
        self.timeout
    }

    /// True when a reply may still be in flight on this socket: the next request must go on a
    /// fresh connection ([`Self::reopen`]).
    pub(crate) fn is_stale(&self) -> bool {
        self.stale
    }

    /// Shuts the old socket and connects afresh; unread bytes of the old one are dropped. The
    /// link stays stale if this fails, so the next request tries again.
    pub(crate) fn reopen(&mut self) -> io::Result<()> {
        self.transport.reopen()?;
        self.len = 0;
        self.consumed = 0;
        self.stale = false;
        Ok(())
    }

    /// Writes `request` (which carries its own line break).
    pub(crate) fn send(&mut self, request: &[u8]) -> io::Result<()> {
        self.transport.write_all(request)
    }

    /// Reads one reply line (without `\n`; a `\r` stays for the caller to trim) that must be
    /// whole within the link's timeout from now.
    pub(crate) fn read_line(&mut self) -> Result<&str, LineError> {
        let deadline = Instant::now() + self.timeout;
        if self.consumed > 0 {
            self.buf.copy_within(self.consumed..self.len, 0);
            self.len -= self.consumed;
            self.consumed = 0;
        }
        loop {
            if let Some(end) = self.buf[..self.len].iter().position(|&b| b == b'\n') {
                self.consumed = end + 1;
                return std::str::from_utf8(&self.buf[..end]).map_err(|_| {
                    LineError::Io(io::Error::new(
                        io::ErrorKind::InvalidData,
                        "reply line is not UTF-8",
                    ))
                });
            }
            if self.len == self.buf.len() {
                self.stale = true;
                return Err(LineError::TooLong);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                self.stale = true;
                return Err(LineError::Timeout);
            }
            self.transport
                .set_read_timeout(left)
                .map_err(LineError::Io)?;
            match self.transport.read(&mut self.buf[self.len..]) {
                Ok(0) => return Err(LineError::Closed),
                Ok(n) => self.len += n,
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    self.stale = true;
                    return Err(LineError::Timeout);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(LineError::Io(e)),
            }
        }
    }
}
