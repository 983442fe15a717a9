//! The second process of the cross-process measurements: `grop-latency-peer`, found next to
//! the running program (or built), spawned per measurement and always reaped.
//!
//! Protocol: the peer prints `ready ...` on stdout once set up, then reads commands (one byte
//! per frame for the camera measurement) on stdin; it prints `result ...` lines with what it
//! measured and exits when stdin closes. Any other line is kept ([`Peer::notes`]).

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use crate::BenchError;

/// The peer binary's file name.
pub const PEER_BIN: &str = "grop-latency-peer";

/// How long a peer gets to set up (iceoryx2 services of 3.5 MiB frames, sockets).
pub const READY_TIMEOUT: Duration = Duration::from_secs(20);

/// Finds `grop-latency-peer` next to the running program or one folder up (a test binary lives
/// in `target/<profile>/deps`). With `build`, first runs `cargo build -p latency --bin
/// grop-latency-peer` (with `--release` when the running program is a release build) in this
/// workspace, if its sources are there.
pub fn locate(build: bool) -> Result<PathBuf, BenchError> {
    locate_built_with(build, &[])
}

/// [`locate`], building the peer in one `cargo build` together with `packages` (the running
/// program's own package), so that shared dependencies get the features the program's own
/// build gave them and are not compiled again (cargo unifies features per build).
pub fn locate_built_with(build: bool, packages: &[&str]) -> Result<PathBuf, BenchError> {
    let exe = std::env::current_exe().map_err(BenchError::io("locating the running program"))?;
    let dir = exe
        .parent()
        .ok_or_else(|| BenchError::Peer("the running program has no folder".into()))?
        .to_path_buf();
    if build {
        let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../Cargo.toml");
        if manifest.is_file() {
            let release = dir.components().any(|c| c.as_os_str() == "release");
            let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
            let mut cmd = Command::new(cargo);
            cmd.arg("build")
                .arg("--manifest-path")
                .arg(&manifest)
                .args(["-p", "latency"]);
            for p in packages {
                cmd.args(["-p", p]);
            }
            cmd.args(["--bin", PEER_BIN]);
            if release {
                cmd.arg("--release");
            }
            let status = cmd
                .status()
                .map_err(BenchError::io("running cargo build for grop-latency-peer"))?;
            if !status.success() {
                return Err(BenchError::Peer(format!(
                    "cargo build -p latency --bin {PEER_BIN} failed ({status})"
                )));
            }
        }
    }
    let candidates = [Some(dir.as_path()), dir.parent()];
    candidates
        .into_iter()
        .flatten()
        .map(|d| d.join(PEER_BIN))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            BenchError::Peer(format!(
                "{PEER_BIN} is not next to {} (build it: cargo build --release -p latency --bin {PEER_BIN})",
                exe.display()
            ))
        })
}

/// A running peer process. Dropping it closes its stdin, then kills it if it has not exited
/// within a second, and reaps it either way.
pub struct Peer {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: Receiver<String>,
    notes: Vec<String>,
    what: String,
}

impl Peer {
    /// Starts `exe` with `args` and waits for its `ready` line; returns the peer and the rest
    /// of that line.
    pub fn spawn(exe: &Path, args: &[String]) -> Result<(Self, String), BenchError> {
        let what = format!("{} {}", PEER_BIN, args.join(" "));
        let mut child = Command::new(exe)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(BenchError::io(format!("starting {}", exe.display())))?;
        let stdin = child.stdin.take();
        let Some(stdout) = child.stdout.take() else {
            let _ = child.kill();
            let _ = child.wait();
            return Err(BenchError::Peer("no stdout pipe".into()));
        };
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { return };
                if tx.send(line).is_err() {
                    return;
                }
            }
        });
        let mut peer = Self {
            child,
            stdin,
            lines,
            notes: Vec::new(),
            what,
        };
        let ready = peer.expect("ready", READY_TIMEOUT)?;
        Ok((peer, ready))
    }

    /// The peer's process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Waits up to `timeout` for a line starting with `keyword` (and a space or the end);
    /// returns the rest of it. Other lines are kept as notes.
    pub fn expect(&mut self, keyword: &str, timeout: Duration) -> Result<String, BenchError> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    if let Some(rest) = line.strip_prefix(keyword) {
                        if rest.is_empty() || rest.starts_with(' ') {
                            return Ok(rest.trim().to_owned());
                        }
                    }
                    if let Some(error) = line.strip_prefix("error ") {
                        return Err(BenchError::Peer(format!("{}: {error}", self.what)));
                    }
                    self.notes.push(line);
                }
                Err(RecvTimeoutError::Timeout) => {
                    return Err(BenchError::Timeout {
                        what: format!("`{keyword}` from {}", self.what),
                        after: timeout,
                    });
                }
                Err(RecvTimeoutError::Disconnected) => {
                    let status = self.child.try_wait().ok().flatten();
                    return Err(BenchError::Peer(format!(
                        "{} ended before `{keyword}` ({})",
                        self.what,
                        status.map_or_else(|| "still running".to_owned(), |s| s.to_string())
                    )));
                }
            }
        }
    }

    /// Lines the peer printed that were not asked for (e.g. its real-time report).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Writes `bytes` to the peer's stdin.
    pub fn send(&mut self, bytes: &[u8]) -> Result<(), BenchError> {
        let stdin = self
            .stdin
            .as_mut()
            .ok_or_else(|| BenchError::Peer("stdin already closed".into()))?;
        stdin
            .write_all(bytes)
            .and_then(|()| stdin.flush())
            .map_err(BenchError::io(format!("writing to {}", self.what)))
    }

    /// Closes stdin (the peer's signal to finish) and waits up to `timeout` for it to exit,
    /// killing it after that. Returns its exit status.
    pub fn finish(&mut self, timeout: Duration) -> Result<ExitStatus, BenchError> {
        self.stdin = None;
        let deadline = Instant::now() + timeout;
        loop {
            match self.child.try_wait() {
                Ok(Some(status)) => return Ok(status),
                Ok(None) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(2));
                }
                Ok(None) => {
                    let _ = self.child.kill();
                    return self
                        .child
                        .wait()
                        .map_err(BenchError::io(format!("reaping {}", self.what)));
                }
                Err(e) => return Err(BenchError::io(format!("waiting for {}", self.what))(e)),
            }
        }
    }

    /// [`finish`](Self::finish), then fails unless the peer exited successfully.
    pub fn finish_ok(&mut self, timeout: Duration) -> Result<(), BenchError> {
        let status = self.finish(timeout)?;
        if status.success() {
            Ok(())
        } else {
            Err(BenchError::Peer(format!(
                "{} exited with {status}",
                self.what
            )))
        }
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        let _ = self.finish(Duration::from_secs(1));
    }
}

/// Parses `key=value` pairs separated by spaces (a `result` line).
pub fn fields(line: &str) -> impl Iterator<Item = (&str, &str)> {
    line.split_whitespace().filter_map(|kv| kv.split_once('='))
}

/// The value of `key` in a `result` line, parsed.
pub fn field<T: std::str::FromStr>(line: &str, key: &str) -> Result<T, BenchError> {
    fields(line)
        .find(|(k, _)| *k == key)
        .and_then(|(_, v)| v.parse().ok())
        .ok_or_else(|| BenchError::Peer(format!("result line lacks a readable {key}=: {line:?}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn result_fields_parse() {
        let line = "count=3 p50_ns=100 name=x";
        assert_eq!(field::<u64>(line, "p50_ns").ok(), Some(100));
        assert_eq!(field::<usize>(line, "count").ok(), Some(3));
        assert!(field::<u64>(line, "name").is_err());
        assert!(field::<u64>(line, "missing").is_err());
    }
}
