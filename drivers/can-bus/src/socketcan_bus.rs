//! The robot's bus: a Linux SocketCAN raw socket through the `socketcan` crate.

use std::io::ErrorKind;
use std::time::{Duration, Instant};

use socketcan::{EmbeddedFrame, Socket, SocketOptions};

use crate::{CanBus, CanFrame, CanId, RecvError, SendError};

/// Why a SocketCAN interface could not be opened.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OpenError {
    /// No such interface, no CAN support in the kernel, or no permission.
    #[error(
        "opening SocketCAN interface {ifname} failed (does `ip link show {ifname}` list it, up?)"
    )]
    Open {
        /// Interface name.
        ifname: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// A socket option could not be set.
    #[error("configuring SocketCAN interface {ifname} ({what}) failed")]
    Configure {
        /// Interface name.
        ifname: String,
        /// Which option.
        what: &'static str,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
}

/// Whether a network interface of this name exists (e.g. `vcan0` for the SocketCAN tests).
pub fn interface_exists(ifname: &str) -> bool {
    !ifname.is_empty()
        && !ifname.contains('/')
        && std::path::Path::new("/sys/class/net").join(ifname).exists()
}

/// A node on a SocketCAN interface (`can0` on the robot, `vcan0` in tests).
///
/// The socket is non-blocking, does not receive its own frames (the kernel default), and
/// receives controller error frames, which [`CanBus::try_recv`] reports as
/// [`RecvError::ErrorFrame`].
///
/// ```no_run
/// use can_bus::{CanBus, CanFrame, CanId, SocketCanBus};
/// let mut bus = SocketCanBus::open("can0")?;
/// bus.send(&CanFrame::new(CanId::Standard(0x500), &[0; 8])?)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct SocketCanBus {
    ifname: String,
    socket: socketcan::CanSocket,
}

impl SocketCanBus {
    /// Opens a raw CAN socket on `ifname`.
    pub fn open(ifname: &str) -> Result<Self, OpenError> {
        let socket = socketcan::CanSocket::open(ifname).map_err(|source| OpenError::Open {
            ifname: ifname.to_owned(),
            source,
        })?;
        let configure = |what: &'static str| {
            move |source| OpenError::Configure {
                ifname: ifname.to_owned(),
                what,
                source,
            }
        };
        socket
            .set_nonblocking(true)
            .map_err(configure("non-blocking mode"))?;
        socket
            .set_recv_own_msgs(false)
            .map_err(configure("no reception of own frames"))?;
        socket
            .set_error_filter_accept_all()
            .map_err(configure("error frame reception"))?;
        Ok(Self {
            ifname: ifname.to_owned(),
            socket,
        })
    }

    /// The interface name.
    pub fn ifname(&self) -> &str {
        &self.ifname
    }

    fn convert(&self, frame: socketcan::CanFrame) -> Result<CanFrame, RecvError> {
        match frame {
            socketcan::CanFrame::Data(data_frame) => {
                let id = match data_frame.id() {
                    socketcan::Id::Standard(id) => CanId::Standard(id.as_raw()),
                    socketcan::Id::Extended(id) => CanId::Extended(id.as_raw()),
                };
                // The kernel guarantees a valid frame; a failure here would be a kernel bug,
                // reported rather than trusted.
                CanFrame::new(id, data_frame.data()).map_err(|error| RecvError::Malformed {
                    bus: self.ifname.clone(),
                    sender: "kernel".to_owned(),
                    detail: error.to_string(),
                })
            }
            socketcan::CanFrame::Remote(remote) => Err(RecvError::UnsupportedFrame {
                bus: self.ifname.clone(),
                kind: "remote (RTR)",
                id: match remote.id() {
                    socketcan::Id::Standard(id) => format!("{:03X}", id.as_raw()),
                    socketcan::Id::Extended(id) => format!("{:08X}", id.as_raw()),
                },
            }),
            socketcan::CanFrame::Error(error) => Err(RecvError::ErrorFrame {
                bus: self.ifname.clone(),
                detail: error.into_error().to_string(),
            }),
        }
    }
}

impl CanBus for SocketCanBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), SendError> {
        let id: socketcan::Id = match frame.id() {
            CanId::Standard(raw) => socketcan::StandardId::new(raw).map(Into::into),
            CanId::Extended(raw) => socketcan::ExtendedId::new(raw).map(Into::into),
        }
        .ok_or_else(|| SendError::Io {
            bus: self.ifname.clone(),
            source: std::io::Error::new(ErrorKind::InvalidInput, "CAN id out of range"),
        })?;
        let raw_frame =
            socketcan::CanFrame::new(id, frame.data()).ok_or_else(|| SendError::Io {
                bus: self.ifname.clone(),
                source: std::io::Error::new(ErrorKind::InvalidInput, "CAN data too long"),
            })?;
        match self.socket.write_frame(&raw_frame) {
            Ok(()) => Ok(()),
            // ENOBUFS: the interface queue is full (nobody acks, or bus-off). EAGAIN: the socket
            // send buffer is full. Both mean "not sent, try later".
            Err(error)
                if error.kind() == ErrorKind::WouldBlock
                    || error.raw_os_error() == Some(libc::ENOBUFS) =>
            {
                Err(SendError::TxQueueFull {
                    bus: self.ifname.clone(),
                })
            }
            Err(source) => Err(SendError::Io {
                bus: self.ifname.clone(),
                source,
            }),
        }
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>, RecvError> {
        match self.socket.read_frame() {
            Ok(frame) => self.convert(frame).map(Some),
            Err(error) if error.kind() == ErrorKind::WouldBlock => Ok(None),
            Err(source) => Err(RecvError::Io {
                bus: self.ifname.clone(),
                source,
            }),
        }
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, RecvError> {
        let start = Instant::now();
        loop {
            if let Some(frame) = self.try_recv()? {
                return Ok(Some(frame));
            }
            let Some(remaining) = timeout.checked_sub(start.elapsed()) else {
                return Ok(None);
            };
            if remaining.is_zero() {
                return Ok(None);
            }
            // poll() until readable or timed out, then read without blocking.
            match self.socket.read_frame_timeout(remaining) {
                Ok(frame) => return self.convert(frame).map(Some),
                Err(error)
                    if matches!(
                        error.kind(),
                        ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                    ) => {}
                Err(source) => {
                    return Err(RecvError::Io {
                        bus: self.ifname.clone(),
                        source,
                    });
                }
            }
        }
    }
}
