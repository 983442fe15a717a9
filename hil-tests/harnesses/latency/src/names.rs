//! Names for the services, buses and socket files of one measurement: process id plus a
//! per-process counter, so that parallel runs (tests, two suites) and leftovers of a killed run
//! never meet.

use std::sync::atomic::{AtomicU64, Ordering};

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// `grop-latency-<kind>-<pid>-<n>`: unique on this host while this process lives. `kind` should
/// be short ASCII letters/digits/`-` (the result is used as an iceoryx2 service name, a virtual
/// CAN bus name, at most 64 bytes, and a file name).
pub fn unique(kind: &str) -> String {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    format!("grop-latency-{kind}-{}-{n}", std::process::id())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_differ_and_carry_the_pid() {
        let a = unique("cam");
        let b = unique("cam");
        assert_ne!(a, b);
        assert!(a.contains(&std::process::id().to_string()));
        assert!(a.len() <= 64);
    }
}
