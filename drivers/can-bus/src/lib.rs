//! The CAN bus seen by the drivers: one [`CanBus`] trait, three backends.
//!
//! - [`SocketCanBus`]: a Linux SocketCAN interface (`can0` on the robot, `vcan0` in CI where the
//!   kernel has vcan), through the `socketcan` crate.
//! - [`VirtualCanBus`]: a userspace bus on iceoryx2 publish-subscribe that several processes
//!   join by name, for hardware-in-the-loop runs on kernels without CAN. See `docs/can-bus.md`.
//! - [`MemoryBus`]: an in-process bus for unit tests.
//!
//! Every backend behaves like a broadcast bus: a node receives every other node's frames, never
//! its own, in send order. [`conformance`] checks this once for every backend.
//!
//! ```
//! use std::time::Duration;
//! use can_bus::{CanBus, CanFrame, CanId, MemoryBus};
//!
//! let bus = MemoryBus::new(); // or VirtualCanBus::join("hil", "driver")?, SocketCanBus::open("can0")?
//! let (mut driver, mut base) = (bus.join(), bus.join());
//! driver.send(&CanFrame::new(CanId::Standard(0x500), &[0, 0, 0, 1])?)?;
//! let frame = base.recv_timeout(Duration::from_millis(100))?;
//! assert_eq!(frame.map(|f| f.data().to_vec()), Some(vec![0, 0, 0, 1]));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::time::Duration;

pub mod conformance;
mod error;
mod frame;
mod memory;
mod os;
mod peer_table;
mod socketcan_bus;
mod virtual_bus;

pub use error::{RecvError, SendError};
pub use frame::{
    CanFrame, CanId, FrameError, MAX_DATA_LEN, MAX_EXTENDED_ID, MAX_STANDARD_ID, ParseFrameError,
};
pub use memory::{DEFAULT_MEMORY_QUEUE_DEPTH, MemoryBus, MemoryBusNode};
pub use socketcan_bus::{OpenError, SocketCanBus, interface_exists};
#[doc(hidden)]
pub use virtual_bus::fuzz_decode_wire_frame;
pub use virtual_bus::{JoinError, PEERS_PER_NODE, VirtualBusConfig, VirtualCanBus};

/// A node on a CAN bus: sends frames to every other node, receives theirs.
///
/// Implementations never deliver a node's own frames back to it, keep each sender's frames in
/// order, and never block in [`send`](CanBus::send) or [`try_recv`](CanBus::try_recv).
pub trait CanBus {
    /// Puts one frame on the bus. An error means the frame was not sent.
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError>;

    /// The oldest frame received and not yet read, or `None` right away if there is none.
    fn try_recv(&mut self) -> Result<Option<CanFrame>, RecvError>;

    /// Like [`try_recv`](CanBus::try_recv), but waits up to `timeout` for a frame (sleeping, not
    /// spinning). `None` means nothing arrived in time.
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, RecvError>;
}

impl<B: CanBus + ?Sized> CanBus for &mut B {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        (**self).send(frame)
    }
    fn try_recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        (**self).try_recv()
    }
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, RecvError> {
        (**self).recv_timeout(timeout)
    }
}

impl<B: CanBus + ?Sized> CanBus for Box<B> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        (**self).send(frame)
    }
    fn try_recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        (**self).try_recv()
    }
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, RecvError> {
        (**self).recv_timeout(timeout)
    }
}
