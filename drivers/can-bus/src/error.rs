//! One error enum per bus operation.

/// Why a frame could not be sent. The frame was not put on the bus.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SendError {
    /// The transmit queue is full (SocketCAN `ENOBUFS`, usually a bus without other nodes to
    /// acknowledge frames, or a bus-off controller). Retrying later may succeed.
    #[error("CAN transmit queue on {bus} is full (no node acknowledging frames, or bus-off)")]
    TxQueueFull {
        /// Interface or virtual bus name.
        bus: String,
    },
    /// The operating system refused the write (interface down, removed, ...).
    #[error("writing a CAN frame to {bus} failed")]
    Io {
        /// Interface name.
        bus: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The iceoryx2 transport of the virtual bus failed.
    #[error("sending on virtual CAN bus {bus} failed: {detail}")]
    Ipc {
        /// Virtual bus name.
        bus: String,
        /// iceoryx2's description of the failure.
        detail: String,
    },
}

/// Why receiving failed. The bus stays usable unless the variant says otherwise.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecvError {
    /// The operating system refused the read.
    #[error("reading a CAN frame from {bus} failed")]
    Io {
        /// Interface name.
        bus: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The controller reported an error frame (bus errors, bus-off, lost arbitration, ...).
    /// Only SocketCAN produces these; the next receive may succeed.
    #[error("CAN error frame on {bus}: {detail}")]
    ErrorFrame {
        /// Interface name.
        bus: String,
        /// The decoded error class.
        detail: String,
    },
    /// A frame this crate does not represent (remote/RTR request). It was consumed.
    #[error("unsupported {kind} frame with id {id} on {bus}")]
    UnsupportedFrame {
        /// Interface or virtual bus name.
        bus: String,
        /// What kind of frame it was.
        kind: &'static str,
        /// Its identifier, in candump notation.
        id: String,
    },
    /// Another node put bytes on the virtual bus that are not a valid CAN frame (id out of range,
    /// length above 8). It was consumed.
    #[error("malformed frame on virtual CAN bus {bus} from {sender}: {detail}")]
    Malformed {
        /// Virtual bus name.
        bus: String,
        /// The sending node, as far as known.
        sender: String,
        /// What was wrong.
        detail: String,
    },
    /// The iceoryx2 transport of the virtual bus failed.
    #[error("receiving on virtual CAN bus {bus} failed: {detail}")]
    Ipc {
        /// Virtual bus name.
        bus: String,
        /// iceoryx2's description of the failure.
        detail: String,
    },
}
