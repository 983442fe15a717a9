//! A one-shot loopback server that plays the controller's side of a TCP connection: it sends the
//! fuzzer's bytes, closes its sending side, and drains whatever the client sends until the client
//! closes. The clients under test connect to it through their public `connect(addr, ...)`, so
//! they run unchanged.

use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// How long the server waits for the client to connect before giving up on this input (a
/// client always connects at once on loopback; this only bounds a harness bug).
const ACCEPT_WAIT: Duration = Duration::from_secs(5);

thread_local! {
    /// One listener per thread, for all inputs: a fresh port per input would make every run
    /// search an ever fuller port table (each finished connection waits out TCP's TIME_WAIT
    /// for a minute), and runs slowed down ten-fold within seconds.
    static LISTENER: (TcpListener, SocketAddr) = {
        let listener = match TcpListener::bind("127.0.0.1:0") {
            Ok(l) => l,
            Err(e) => panic!("cannot listen on loopback: {e}"),
        };
        if let Err(e) = listener.set_nonblocking(true) {
            panic!("cannot make the loopback listener non-blocking: {e}");
        }
        let addr = match listener.local_addr() {
            Ok(a) => a,
            Err(e) => panic!("loopback listener has no address: {e}"),
        };
        (listener, addr)
    };
}

/// The server side of one input: one connection on this thread's listener. Inputs of one
/// thread run one after the other, so the first connection accepted is always this input's.
/// A client that reconnects (the gripper and dashboard clients reopen a link that went stale)
/// finds a controller that has nothing more to say: each later connection is accepted and
/// closed at once, until the server is dropped. (Left in the listener's backlog, a reconnect
/// waited out the client's whole reply timeout, 40 s for one input, and the next input's
/// server would have accepted it instead of that input's own client.)
pub(crate) struct OneShotServer {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl OneShotServer {
    /// Starts serving `bytes` to the next connection.
    pub(crate) fn serve(bytes: Vec<u8>) -> Self {
        let (listener, addr) = LISTENER.with(|(l, a)| match l.try_clone() {
            Ok(l) => (l, *a),
            Err(e) => panic!("cannot share the loopback listener: {e}"),
        });
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = Arc::clone(&stop);
        let thread = thread::spawn(move || {
            let deadline = Instant::now() + ACCEPT_WAIT;
            let mut stream = loop {
                match listener.accept() {
                    Ok((stream, _)) => break stream,
                    Err(e) if e.kind() == ErrorKind::WouldBlock && Instant::now() < deadline => {
                        thread::sleep(Duration::from_micros(20));
                    }
                    Err(_) => return,
                }
            };
            if stream.set_nonblocking(false).is_err() {
                return;
            }
            // The client may close early (an error ends its session): write errors are fine.
            let _ = stream.write_all(&bytes);
            let _ = stream.shutdown(Shutdown::Write);
            let mut sink = [0u8; 4096];
            while let Ok(n) = stream.read(&mut sink) {
                if n == 0 {
                    break;
                }
            }
            drop(stream);
            // Reconnects: accepted and closed (the client reads end of stream at once).
            while !stopped.load(Ordering::Acquire) {
                match listener.accept() {
                    Ok((late, _)) => {
                        let _ = late.shutdown(Shutdown::Both);
                    }
                    Err(e) if e.kind() == ErrorKind::WouldBlock => {
                        thread::sleep(Duration::from_micros(20));
                    }
                    Err(_) => return,
                }
            }
        });
        Self {
            addr,
            stop,
            thread: Some(thread),
        }
    }

    /// Where the client connects.
    pub(crate) fn addr(&self) -> SocketAddr {
        self.addr
    }
}

impl Drop for OneShotServer {
    /// Waits for the server thread; the client must be gone by now (its connection closed).
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpStream;

    /// The first connection gets the input's bytes; a reconnect (a client reopening a stale
    /// link) reads end of stream at once instead of waiting out its timeout in the listener's
    /// backlog, and the next input's server still serves its own client first.
    #[test]
    fn a_reconnect_reads_end_of_stream_and_the_next_input_is_served_first() {
        let read_all = |stream: &mut TcpStream| {
            stream.set_read_timeout(Some(Duration::from_secs(10))).ok();
            let mut got = Vec::new();
            stream.read_to_end(&mut got).map(|_| got)
        };
        let server = OneShotServer::serve(b"first\n".to_vec());
        let mut first = TcpStream::connect(server.addr()).unwrap();
        assert_eq!(read_all(&mut first).unwrap(), b"first\n");
        drop(first);
        for _ in 0..3 {
            let mut again = TcpStream::connect(server.addr()).unwrap();
            // Before: no one accepted it, and the read timed out (an error, not end of stream).
            let got = read_all(&mut again);
            assert!(matches!(&got, Ok(b) if b.is_empty()), "{got:?}");
        }
        drop(server);
        let next = OneShotServer::serve(b"second\n".to_vec());
        let mut client = TcpStream::connect(next.addr()).unwrap();
        assert_eq!(read_all(&mut client).unwrap(), b"second\n");
        drop(client);
        drop(next);
    }
}
