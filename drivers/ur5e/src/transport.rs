//! The byte stream under the arm's clients: a TCP connection to the controller
//! ([`TcpTransport`]), or anything that stands in for one (a test double, an in-memory stream
//! for fuzzing), so that the clients' framing, deadlines, reconnects and reply parsing run the
//! same over either. [`crate::dashboard::DashboardClient`], [`crate::gripper::RobotiqGripper`]
//! and [`crate::rtde::RtdeClient`] are generic over it and default to TCP.

use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::time::Duration;

/// A connection a client reads and writes (see the module docs).
pub trait Transport: Read + Write {
    /// Bounds the wait of the next blocking read: a read that would wait longer than `left`
    /// fails with [`io::ErrorKind::TimedOut`] or [`io::ErrorKind::WouldBlock`].
    fn set_read_timeout(&mut self, left: Duration) -> io::Result<()>;
    /// In non-blocking mode a read that has nothing to return fails at once with
    /// [`io::ErrorKind::WouldBlock`].
    fn set_nonblocking(&mut self, on: bool) -> io::Result<()>;
    /// Ends this connection: the peer sees it closed, unread bytes are lost.
    fn shutdown(&mut self);
    /// Ends this connection and opens a fresh one to the same peer. On failure the old one
    /// stays ended, and a later call may try again.
    fn reopen(&mut self) -> io::Result<()>;
    /// The peer, for errors and logs.
    fn peer(&self) -> SocketAddr;
}

/// A TCP connection as a [`Transport`]: no Nagle delay (small packages at 500 Hz, and one line
/// per request), a connect timeout, and a write timeout.
#[derive(Debug)]
pub struct TcpTransport {
    addr: SocketAddr,
    stream: TcpStream,
    connect_timeout: Duration,
    write_timeout: Duration,
}

impl TcpTransport {
    /// Connects within `connect_timeout`; every write must finish within `write_timeout`.
    pub fn connect(
        addr: SocketAddr,
        connect_timeout: Duration,
        write_timeout: Duration,
    ) -> io::Result<Self> {
        Ok(Self {
            addr,
            stream: Self::open(addr, connect_timeout, write_timeout)?,
            connect_timeout,
            write_timeout,
        })
    }

    fn open(
        addr: SocketAddr,
        connect_timeout: Duration,
        write_timeout: Duration,
    ) -> io::Result<TcpStream> {
        let stream = TcpStream::connect_timeout(&addr, connect_timeout)?;
        stream.set_nodelay(true)?;
        stream.set_write_timeout(Some(write_timeout))?;
        Ok(stream)
    }
}

impl Read for TcpTransport {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.stream.read(buf)
    }
}

impl Write for TcpTransport {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.stream.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.stream.flush()
    }
}

impl Transport for TcpTransport {
    fn set_read_timeout(&mut self, left: Duration) -> io::Result<()> {
        self.stream.set_read_timeout(Some(left))
    }

    fn set_nonblocking(&mut self, on: bool) -> io::Result<()> {
        self.stream.set_nonblocking(on)
    }

    fn shutdown(&mut self) {
        let _ = self.stream.shutdown(Shutdown::Both);
    }

    fn reopen(&mut self) -> io::Result<()> {
        self.shutdown();
        self.stream = Self::open(self.addr, self.connect_timeout, self.write_timeout)?;
        Ok(())
    }

    fn peer(&self) -> SocketAddr {
        self.addr
    }
}
