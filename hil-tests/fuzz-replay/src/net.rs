//! A one-shot loopback server that plays the controller's side of a TCP connection: it sends the
//! fuzzer's bytes, closes its sending side, and drains whatever the client sends until the client
//! closes. The clients under test connect to it through their public `connect(addr, ...)`, so
//! they run unchanged.

use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener};
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
/// thread run one after the other and each client connects exactly once, so the connection
/// accepted is always this input's.
pub(crate) struct OneShotServer {
    addr: SocketAddr,
    thread: Option<JoinHandle<()>>,
}

impl OneShotServer {
    /// Starts serving `bytes` to the next connection.
    pub(crate) fn serve(bytes: Vec<u8>) -> Self {
        let (listener, addr) = LISTENER.with(|(l, a)| match l.try_clone() {
            Ok(l) => (l, *a),
            Err(e) => panic!("cannot share the loopback listener: {e}"),
        });
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
        });
        Self {
            addr,
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
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}
