//! In-memory [`Transport`]s, so that the arm's clients (framing, deadlines, reconnects and reply
//! parsing) run at their decoders' speed instead of a loopback connection's (~1 ms per input):
//! [`ScriptedLine`] for the line protocols, [`ScriptedStream`] for RTDE.
//!
//! [`ScriptedLine`] plays a script of connections. The script is the server's bytes with three markers that never occur in UTF-8 text:
//! - `0xFF` ends a connection: reads return end of stream until the client reopens, and the
//!   next connection plays the bytes after the marker. A reopen with no connection left is
//!   refused.
//! - `0xFE` makes the read at that point time out (the reply's deadline passed).
//! - `0xFD` ends a read there, so a reply can arrive split across reads.
//!
//! Every connection first sends `greeting` (the dashboard's welcome line, when the target asks
//! for it). The transport checks the clients' promise about stale replies: after a read timed
//! out, no request may go out on that connection (the client must reopen first), and every
//! request is exactly one line.

use std::io::{self, Read, Write};
use std::net::SocketAddr;
use std::time::Duration;

use ur5e::transport::Transport;

/// Ends a connection.
const CLOSE: u8 = 0xFF;
/// A read that times out.
const TIMEOUT: u8 = 0xFE;
/// A read boundary.
const SPLIT: u8 = 0xFD;

/// See the module docs.
#[derive(Debug)]
pub(crate) struct ScriptedLine<'a> {
    greeting: &'a [u8],
    /// What is left of the greeting on this connection.
    greeting_left: &'a [u8],
    /// What is left of this connection's bytes.
    current: &'a [u8],
    /// The later connections, if any.
    later: Option<&'a [u8]>,
    /// A read on this connection timed out: no request may go out on it.
    timed_out: bool,
    /// Connections opened so far.
    pub(crate) connections: u32,
}

/// The first connection of `script` and the rest after its `CLOSE`, if there is one.
fn split_connection(script: &[u8]) -> (&[u8], Option<&[u8]>) {
    match script.iter().position(|&b| b == CLOSE) {
        Some(end) => (&script[..end], Some(&script[end + 1..])),
        None => (script, None),
    }
}

impl<'a> ScriptedLine<'a> {
    pub(crate) fn new(script: &'a [u8], greeting: &'a [u8]) -> Self {
        let (current, later) = split_connection(script);
        Self {
            greeting,
            greeting_left: greeting,
            current,
            later,
            timed_out: false,
            connections: 1,
        }
    }
}

impl Read for ScriptedLine<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        if !self.greeting_left.is_empty() {
            let n = self.greeting_left.len().min(buf.len());
            buf[..n].copy_from_slice(&self.greeting_left[..n]);
            self.greeting_left = &self.greeting_left[n..];
            return Ok(n);
        }
        while let Some((&SPLIT, rest)) = self.current.split_first() {
            self.current = rest;
        }
        match self.current.split_first() {
            None => Ok(0),
            Some((&TIMEOUT, rest)) => {
                self.current = rest;
                self.timed_out = true;
                Err(io::Error::new(io::ErrorKind::TimedOut, "scripted timeout"))
            }
            Some(_) => {
                let data = self
                    .current
                    .iter()
                    .position(|&b| b == SPLIT || b == TIMEOUT)
                    .unwrap_or(self.current.len());
                let n = data.min(buf.len());
                buf[..n].copy_from_slice(&self.current[..n]);
                self.current = &self.current[n..];
                Ok(n)
            }
        }
    }
}

impl Write for ScriptedLine<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        assert!(
            !self.timed_out,
            "request {:?} went out on a connection whose reply timed out: its late reply \
             could be read as this request's answer",
            String::from_utf8_lossy(buf)
        );
        assert!(
            buf.last() == Some(&b'\n') && buf.iter().filter(|&&b| b == b'\n').count() == 1,
            "a request is not one line: {:?}",
            String::from_utf8_lossy(buf)
        );
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Transport for ScriptedLine<'_> {
    fn set_read_timeout(&mut self, _left: Duration) -> io::Result<()> {
        Ok(())
    }

    fn set_nonblocking(&mut self, _on: bool) -> io::Result<()> {
        Ok(())
    }

    fn shutdown(&mut self) {
        self.greeting_left = b"";
        self.current = b"";
    }

    fn reopen(&mut self) -> io::Result<()> {
        let Some(later) = self.later else {
            return Err(io::Error::new(
                io::ErrorKind::ConnectionRefused,
                "the script has no connection left",
            ));
        };
        let (current, later) = split_connection(later);
        self.current = current;
        self.later = later;
        self.greeting_left = self.greeting;
        self.timed_out = false;
        self.connections += 1;
        Ok(())
    }

    fn peer(&self) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], 0))
    }
}

/// One connection that sends `data` and closes, `max_read` bytes a read at most (0: no limit), so
/// that packages arrive split as the kernel may split them. Every write must be one whole RTDE
/// package (its size field says its length). It cannot be reopened.
#[derive(Debug)]
pub(crate) struct ScriptedStream<'a> {
    data: &'a [u8],
    max_read: usize,
}

impl<'a> ScriptedStream<'a> {
    pub(crate) fn new(data: &'a [u8], max_read: usize) -> Self {
        Self { data, max_read }
    }
}

impl Read for ScriptedStream<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let cap = if self.max_read == 0 {
            buf.len()
        } else {
            self.max_read.min(buf.len())
        };
        let n = cap.min(self.data.len());
        buf[..n].copy_from_slice(&self.data[..n]);
        self.data = &self.data[n..];
        Ok(n)
    }
}

impl Write for ScriptedStream<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let size = buf
            .first_chunk::<2>()
            .map(|s| usize::from(u16::from_be_bytes(*s)));
        assert_eq!(
            size,
            Some(buf.len()),
            "a write is not one whole package: {buf:?}"
        );
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Transport for ScriptedStream<'_> {
    fn set_read_timeout(&mut self, _left: Duration) -> io::Result<()> {
        Ok(())
    }

    fn set_nonblocking(&mut self, _on: bool) -> io::Result<()> {
        Ok(())
    }

    fn shutdown(&mut self) {
        self.data = b"";
    }

    fn reopen(&mut self) -> io::Result<()> {
        self.shutdown();
        Err(io::Error::new(
            io::ErrorKind::ConnectionRefused,
            "a scripted stream has one connection",
        ))
    }

    fn peer(&self) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], 0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markers_split_time_out_and_close() {
        let script = b"ab\xFDcd\xFEef\xFFgh";
        let mut t = ScriptedLine::new(script, b"hi\n");
        let mut buf = [0u8; 16];
        assert_eq!(t.read(&mut buf).unwrap(), 3);
        assert_eq!(&buf[..3], b"hi\n");
        assert_eq!(t.read(&mut buf).unwrap(), 2);
        assert_eq!(&buf[..2], b"ab");
        assert_eq!(t.read(&mut buf).unwrap(), 2);
        assert_eq!(&buf[..2], b"cd");
        let e = t.read(&mut buf).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::TimedOut);
        // A request on the timed-out connection breaks the promise.
        let stale = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let mut copy = ScriptedLine {
                timed_out: true,
                ..ScriptedLine::new(b"", b"")
            };
            let _ = copy.write(b"GET STA\n");
        }));
        assert!(stale.is_err());
        assert_eq!(t.read(&mut buf).unwrap(), 2);
        assert_eq!(&buf[..2], b"ef");
        assert_eq!(t.read(&mut buf).unwrap(), 0, "closed");
        t.reopen().unwrap();
        assert_eq!(t.connections, 2);
        assert_eq!(t.write(b"GET STA\n").unwrap(), 8);
        assert_eq!(t.read(&mut buf).unwrap(), 3);
        assert_eq!(t.read(&mut buf).unwrap(), 2);
        assert_eq!(&buf[..2], b"gh");
        assert_eq!(t.read(&mut buf).unwrap(), 0);
        assert_eq!(
            t.reopen().unwrap_err().kind(),
            io::ErrorKind::ConnectionRefused
        );
    }

    #[test]
    fn a_stream_splits_reads_and_checks_writes() {
        let mut s = ScriptedStream::new(b"abcde", 2);
        let mut buf = [0u8; 16];
        assert_eq!(s.read(&mut buf).unwrap(), 2);
        assert_eq!(s.read(&mut buf).unwrap(), 2);
        assert_eq!(s.read(&mut buf).unwrap(), 1);
        assert_eq!(s.read(&mut buf).unwrap(), 0);
        assert_eq!(s.write(&[0, 3, b'V']).unwrap(), 3);
        let short = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let _ = ScriptedStream::new(b"", 0).write(&[0, 4, b'V']);
        }));
        assert!(short.is_err());
    }
}
