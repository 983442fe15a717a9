//! In-process bus for unit tests of code that talks CAN.

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use crate::{CanBus, CanFrame, RecvError, SendError};

/// Frames a node can hold unread before the oldest are dropped.
pub const DEFAULT_MEMORY_QUEUE_DEPTH: usize = 1024;

/// An in-process CAN bus: every frame a node sends reaches every other node that has joined,
/// in one global order, never the sender itself.
///
/// ```
/// use can_bus::{CanBus, CanFrame, CanId, MemoryBus};
/// let bus = MemoryBus::new();
/// let mut driver = bus.join();
/// let mut device = bus.join();
/// driver.send(&CanFrame::new(CanId::Standard(0x500), &[1, 2])?)?;
/// assert_eq!(device.try_recv()?.map(|f| f.id()), Some(CanId::Standard(0x500)));
/// assert_eq!(driver.try_recv()?, None); // no self-reception
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone)]
pub struct MemoryBus {
    shared: Arc<Shared>,
}

struct Shared {
    state: Mutex<State>,
    frame_arrived: Condvar,
    queue_depth: usize,
}

struct State {
    next_node_id: u64,
    nodes: Vec<NodeQueue>,
}

struct NodeQueue {
    node_id: u64,
    frames: VecDeque<CanFrame>,
    overruns: u64,
}

impl Default for MemoryBus {
    fn default() -> Self {
        Self::new()
    }
}

impl MemoryBus {
    /// A bus whose nodes each buffer [`DEFAULT_MEMORY_QUEUE_DEPTH`] frames.
    pub fn new() -> Self {
        Self::with_queue_depth(DEFAULT_MEMORY_QUEUE_DEPTH)
    }

    /// A bus whose nodes each buffer `queue_depth` frames (at least 1); a node that falls further
    /// behind loses its oldest frames, like a receive FIFO that overruns.
    pub fn with_queue_depth(queue_depth: usize) -> Self {
        Self {
            shared: Arc::new(Shared {
                state: Mutex::new(State {
                    next_node_id: 0,
                    nodes: Vec::new(),
                }),
                frame_arrived: Condvar::new(),
                queue_depth: queue_depth.max(1),
            }),
        }
    }

    /// Connects a new node. It receives frames sent after this call by every other node.
    pub fn join(&self) -> MemoryBusNode {
        let mut state = self.shared.lock();
        let node_id = state.next_node_id;
        state.next_node_id += 1;
        state.nodes.push(NodeQueue {
            node_id,
            frames: VecDeque::with_capacity(self.shared.queue_depth),
            overruns: 0,
        });
        MemoryBusNode {
            shared: Arc::clone(&self.shared),
            node_id,
        }
    }

    /// Number of nodes currently joined.
    pub fn node_count(&self) -> usize {
        self.shared.lock().nodes.len()
    }
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic while holding the lock cannot leave the queues inconsistent (every mutation is
        // a single push/pop), so a poisoned lock is still safe to use.
        self.state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

/// One node on a [`MemoryBus`]; leaves the bus when dropped.
pub struct MemoryBusNode {
    shared: Arc<Shared>,
    node_id: u64,
}

impl MemoryBusNode {
    /// Frames this node lost because it fell more than the queue depth behind.
    pub fn overrun_count(&self) -> u64 {
        let state = self.shared.lock();
        state
            .nodes
            .iter()
            .find(|node| node.node_id == self.node_id)
            .map_or(0, |node| node.overruns)
    }

    fn pop(&self, state: &mut State) -> Option<CanFrame> {
        state
            .nodes
            .iter_mut()
            .find(|node| node.node_id == self.node_id)
            .and_then(|node| node.frames.pop_front())
    }
}

impl CanBus for MemoryBusNode {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        let depth = self.shared.queue_depth;
        let mut state = self.shared.lock();
        for node in state.nodes.iter_mut().filter(|n| n.node_id != self.node_id) {
            if node.frames.len() == depth {
                node.frames.pop_front();
                node.overruns += 1;
            }
            node.frames.push_back(*frame);
        }
        drop(state);
        self.shared.frame_arrived.notify_all();
        Ok(())
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        let mut state = self.shared.lock();
        Ok(self.pop(&mut state))
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, RecvError> {
        let deadline = Instant::now().checked_add(timeout);
        let mut state = self.shared.lock();
        loop {
            if let Some(frame) = self.pop(&mut state) {
                return Ok(Some(frame));
            }
            let now = Instant::now();
            let remaining = match deadline {
                Some(deadline) if deadline > now => deadline - now,
                Some(_) => return Ok(None),
                // A timeout too large for Instant: wait in long slices.
                None => Duration::from_secs(3600),
            };
            state = self
                .shared
                .frame_arrived
                .wait_timeout(state, remaining)
                .unwrap_or_else(|poisoned| poisoned.into_inner())
                .0;
        }
    }
}

impl Drop for MemoryBusNode {
    fn drop(&mut self) {
        let mut state = self.shared.lock();
        state.nodes.retain(|node| node.node_id != self.node_id);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::CanId;

    fn frame(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(CanId::Standard(id), data).unwrap()
    }

    #[test]
    fn slow_reader_loses_oldest_frames_and_counts_them() {
        let bus = MemoryBus::with_queue_depth(4);
        let mut sender = bus.join();
        let mut reader = bus.join();
        for index in 0..10u8 {
            sender.send(&frame(0x100, &[index])).unwrap();
        }
        assert_eq!(reader.overrun_count(), 6);
        let received: Vec<u8> = std::iter::from_fn(|| reader.try_recv().unwrap())
            .map(|f| f.data()[0])
            .collect();
        assert_eq!(received, vec![6, 7, 8, 9]);
    }

    #[test]
    fn dropped_node_leaves_the_bus() {
        let bus = MemoryBus::new();
        let node = bus.join();
        let _other = bus.join();
        assert_eq!(bus.node_count(), 2);
        drop(node);
        assert_eq!(bus.node_count(), 1);
    }

    #[test]
    fn recv_timeout_wakes_on_a_frame_from_another_thread() {
        let bus = MemoryBus::new();
        let mut reader = bus.join();
        let mut sender = bus.join();
        let handle = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            sender.send(&frame(0x42, &[7])).unwrap();
        });
        let received = reader.recv_timeout(Duration::from_secs(10)).unwrap();
        assert_eq!(received, Some(frame(0x42, &[7])));
        handle.join().unwrap();
    }
}
