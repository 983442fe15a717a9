//! Data packets from a UDP socket (the sensor on the robot, or the simulated sensor over
//! loopback in HIL), read without blocking.
#![allow(
    unsafe_code,
    reason = "setsockopt/getsockopt for the receive buffer size"
)]

use std::io;
use std::net::{IpAddr, SocketAddr, ToSocketAddrs, UdpSocket};

use crate::calib::PACKETS_PER_S;
use crate::packet::{DataPacket, PAYLOAD_LEN, PacketError};

/// Receive buffer asked for: 100 ms of packets (75 of 1206 bytes) with the kernel's per-packet
/// overhead (it charges about twice the payload), rounded up to 1 MiB.
pub const RECEIVE_BUFFER_BYTES: usize = 1 << 20;

/// A non-blocking UDP socket that data packets arrive on.
#[derive(Debug)]
pub struct UdpSource {
    socket: UdpSocket,
    buffer: Box<[u8; 2048]>,
    /// Datagrams read.
    pub datagrams: u64,
    /// Datagrams of a length other than 1206 bytes (position packets sent to the wrong port,
    /// truncated datagrams, other traffic).
    pub foreign_length: u64,
    /// The receive buffer the kernel granted (bytes), if it could be read.
    pub receive_buffer_bytes: Option<usize>,
    /// Datagrams dropped unread because they came from another address than the sensor's
    /// ([`UdpSource::only_from`]).
    pub foreign_sender: u64,
    sensor: Option<IpAddr>,
}

fn set_receive_buffer(socket: &UdpSocket, bytes: usize) -> Option<usize> {
    use std::os::fd::AsRawFd;
    let fd = socket.as_raw_fd();
    let wanted = libc::c_int::try_from(bytes).unwrap_or(libc::c_int::MAX);
    let size = std::mem::size_of::<libc::c_int>() as libc::socklen_t;
    // SAFETY: `fd` is an open socket owned by `socket` for the duration of the call; the option
    // value points at a live c_int of the size passed.
    let set = unsafe {
        libc::setsockopt(
            fd,
            libc::SOL_SOCKET,
            libc::SO_RCVBUF,
            (&wanted as *const libc::c_int).cast(),
            size,
        )
    };
    if set != 0 {
        log::warn!(
            "vlp16: SO_RCVBUF {bytes} not set: {}",
            io::Error::last_os_error()
        );
    }
    let mut granted: libc::c_int = 0;
    let mut len = size;
    // SAFETY: as above; `granted` and `len` are live and `len` holds the size of `granted`.
    let got = unsafe {
        libc::getsockopt(
            fd,
            libc::SOL_SOCKET,
            libc::SO_RCVBUF,
            (&mut granted as *mut libc::c_int).cast(),
            &mut len,
        )
    };
    (got == 0).then(|| usize::try_from(granted).unwrap_or(0))
}

impl UdpSource {
    /// Binds a non-blocking socket (port 0: one the OS chooses; [`Self::local_addr`] says
    /// which) and asks for a receive buffer of [`RECEIVE_BUFFER_BYTES`]; a smaller grant is
    /// logged when it holds less than 100 ms of packets.
    pub fn bind(addr: impl ToSocketAddrs) -> io::Result<Self> {
        let socket = UdpSocket::bind(addr)?;
        socket.set_nonblocking(true)?;
        let granted = set_receive_buffer(&socket, RECEIVE_BUFFER_BYTES);
        let needed = (PACKETS_PER_S * 0.1).ceil() as usize * PAYLOAD_LEN;
        if let Some(g) = granted
            && g < needed
        {
            log::warn!("vlp16: receive buffer {g} bytes, below 100 ms of packets ({needed})");
        }
        Ok(Self {
            socket,
            buffer: Box::new([0; 2048]),
            datagrams: 0,
            foreign_length: 0,
            receive_buffer_bytes: granted,
            foreign_sender: 0,
            sensor: None,
        })
    }

    /// Takes datagrams only from `sensor` (the sensor's address on the robot's network): any
    /// other sender's are dropped unread and counted in [`foreign_sender`](Self::foreign_sender).
    /// A local process cannot send from the sensor's address without raw sockets
    /// (`CAP_NET_RAW`), so a forged scan from another program does not reach the monitor
    /// (docs/security.md).
    pub fn only_from(&mut self, sensor: IpAddr) {
        self.sensor = Some(sensor);
    }

    /// The address the socket is bound to.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Reads every datagram waiting, without blocking, and hands each to `f` decoded (or the
    /// error naming what was wrong); returns how many were read.
    pub fn drain(
        &mut self,
        mut f: impl FnMut(Result<DataPacket, PacketError>),
    ) -> io::Result<usize> {
        let mut read = 0;
        loop {
            match self.socket.recv_from(&mut self.buffer[..]) {
                Ok((_, from)) if self.sensor.is_some_and(|ip| ip != from.ip()) => {
                    self.foreign_sender += 1;
                }
                Ok((len, _)) => {
                    read += 1;
                    self.datagrams += 1;
                    if len != PAYLOAD_LEN {
                        self.foreign_length += 1;
                    }
                    f(DataPacket::decode(&self.buffer[..len]));
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(read),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                // An ICMP error from an earlier send (none here) or a transient one: the next
                // drain tries again.
                Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => return Ok(read),
                Err(e) => return Err(e),
            }
        }
    }
}
