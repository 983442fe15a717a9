//! Per-sender state of a virtual-bus node: the last sequence number heard from each sender, to
//! count lost frames from gaps.
//!
//! Sender keys and sequence numbers come from other processes, so neither may be trusted: the
//! table has a fixed capacity (a process cycling through invented keys cannot grow it; the
//! least recently heard sender is evicted and counted), and sequence arithmetic wraps, so no
//! value, `u64::MAX` included, can overflow or panic. Allocated once; `observe` never allocates.

/// One sender's state.
#[derive(Debug, Clone, Copy)]
struct Peer {
    key: u64,
    last_seq: u64,
    /// Value of the table's clock when this sender was last heard.
    heard: u64,
}

/// Bounded map from sender key to last sequence number (linear search: a handful of entries).
#[derive(Debug)]
pub(crate) struct PeerTable {
    peers: Vec<Peer>,
    capacity: usize,
    clock: u64,
    evicted: u64,
}

impl PeerTable {
    /// A table for at most `capacity` senders (at least 1).
    pub(crate) fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        Self {
            peers: Vec::with_capacity(capacity),
            capacity,
            clock: 0,
            evicted: 0,
        }
    }

    /// Records frame `seq` of sender `key`; returns how many of its frames were skipped since
    /// the last one heard. A sender's first frame (or its first after an eviction) counts none;
    /// so does a step back or a repeat: a gap of half the sequence space or more (wrapping) is
    /// read as a step back (a restarted or replaying sender), not as that many losses.
    pub(crate) fn observe(&mut self, key: u64, seq: u64) -> u64 {
        self.clock = self.clock.wrapping_add(1);
        let heard = self.clock;
        if let Some(peer) = self.peers.iter_mut().find(|p| p.key == key) {
            let gap = seq.wrapping_sub(peer.last_seq).wrapping_sub(1);
            peer.last_seq = seq;
            peer.heard = heard;
            return if gap < 1 << 63 { gap } else { 0 };
        }
        if self.peers.len() >= self.capacity {
            let oldest = self
                .peers
                .iter()
                .enumerate()
                // Clock distance, so the order survives the clock wrapping.
                .max_by_key(|(_, p)| heard.wrapping_sub(p.heard))
                .map(|(i, _)| i);
            if let Some(i) = oldest {
                self.peers.swap_remove(i);
                self.evicted = self.evicted.saturating_add(1);
            }
        }
        self.peers.push(Peer {
            key,
            last_seq: seq,
            heard,
        });
        0
    }

    /// Senders evicted to keep the table within its capacity.
    pub(crate) fn evicted(&self) -> u64 {
        self.evicted
    }

    /// Senders in the table.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.peers.len()
    }

    /// Most senders the table holds.
    #[cfg(test)]
    pub(crate) fn capacity(&self) -> usize {
        self.capacity
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_are_counted_across_the_wrap_and_steps_back_are_not() {
        let mut t = PeerTable::new(4);
        assert_eq!(t.observe(7, 10), 0);
        assert_eq!(t.observe(7, 11), 0);
        assert_eq!(t.observe(7, 15), 3);
        assert_eq!(t.observe(7, 15), 0, "repeat");
        assert_eq!(t.observe(7, 2), 0, "step back");
        assert_eq!(t.observe(7, u64::MAX), 0, "far ahead reads as a step back");
        assert_eq!(t.observe(7, 1), 1, "wrapped past 0");
        assert_eq!(t.observe(7, 1 + (1 << 62)), (1 << 62) - 1);
    }

    #[test]
    fn the_least_recently_heard_sender_is_evicted() {
        let mut t = PeerTable::new(2);
        t.observe(1, 0);
        t.observe(2, 0);
        t.observe(1, 1); // 2 is now the least recently heard
        t.observe(3, 0);
        assert_eq!((t.len(), t.evicted()), (2, 1));
        assert_eq!(t.observe(1, 3), 1, "1 was kept");
        assert_eq!(t.observe(2, 5), 0, "2 was evicted: a first frame again");
        assert_eq!(t.evicted(), 2);
    }
}
