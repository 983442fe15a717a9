//! The transport under the driver. The RMP 110 of the paper is documented publicly only over
//! UDP/USB, so the driver talks to a [`RmpLink`], not to CAN directly; [`CanLink`] adapts any
//! [`CanBus`] and a UDP/USB link (with `rmp_codec::packet` framing) can be added beside it.

use can_bus::{CanBus, CanFrame, CanId, RecvError, SendError};
use rmp_codec::RawFrame;

/// Why the link failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LinkError {
    /// The frame was not sent.
    #[error("sending {frame:?} failed: {source}")]
    Send {
        /// The frame.
        frame: RawFrame,
        /// The bus error.
        #[source]
        source: SendError,
    },
    /// Receiving failed (the link may still work on the next try).
    #[error("receiving failed: {0}")]
    Recv(#[from] RecvError),
}

/// A bidirectional frame link to one RMP. Never blocks.
pub trait RmpLink {
    /// Sends one frame.
    fn send(&mut self, frame: &RawFrame) -> Result<(), LinkError>;
    /// The next received RMP frame, or `None` if none is waiting.
    fn try_recv(&mut self) -> Result<Option<RawFrame>, LinkError>;
}

impl<L: RmpLink + ?Sized> RmpLink for &mut L {
    fn send(&mut self, frame: &RawFrame) -> Result<(), LinkError> {
        (**self).send(frame)
    }
    fn try_recv(&mut self) -> Result<Option<RawFrame>, LinkError> {
        (**self).try_recv()
    }
}

/// Converts a codec frame to a bus frame (always a standard id).
pub fn to_can(frame: &RawFrame) -> CanFrame {
    // The codec guarantees an 11-bit id and at most 8 bytes, which is all CanFrame checks.
    CanFrame::new(CanId::Standard(frame.id()), frame.data())
        .unwrap_or_else(|_| unreachable!("RawFrame invariants match CanFrame's"))
}

/// Converts a bus frame to a codec frame; `None` for extended ids (the RMP uses none).
pub fn from_can(frame: &CanFrame) -> Option<RawFrame> {
    match frame.id() {
        CanId::Standard(id) => RawFrame::new(id, frame.data()).ok(),
        CanId::Extended(_) => None,
    }
}

/// [`RmpLink`] over a CAN bus node.
pub struct CanLink<B> {
    bus: B,
    foreign_frames: u64,
}

impl<B: CanBus> CanLink<B> {
    /// Wraps a bus node.
    pub fn new(bus: B) -> Self {
        Self {
            bus,
            foreign_frames: 0,
        }
    }

    /// Frames skipped because they had an extended id.
    pub fn foreign_frames(&self) -> u64 {
        self.foreign_frames
    }

    /// The bus node.
    pub fn bus_mut(&mut self) -> &mut B {
        &mut self.bus
    }
}

impl<B: CanBus> RmpLink for CanLink<B> {
    fn send(&mut self, frame: &RawFrame) -> Result<(), LinkError> {
        self.bus
            .send(&to_can(frame))
            .map_err(|source| LinkError::Send {
                frame: *frame,
                source,
            })
    }

    fn try_recv(&mut self) -> Result<Option<RawFrame>, LinkError> {
        while let Some(frame) = self.bus.try_recv()? {
            match from_can(&frame) {
                Some(raw) => return Ok(Some(raw)),
                None => self.foreign_frames += 1,
            }
        }
        Ok(None)
    }
}
