//! A minimal pcap writer (the classic libpcap format, microsecond stamps, Ethernet link type)
//! for data packets as the sensor sends them: Ethernet, IPv4 and UDP headers from port 2368 to
//! port 2368. Enough for Wireshark, VeloView and `velodyne-decoder` to read the packets; used by
//! the `sim_pcap` example and the third-party check.

use std::io::{self, Write};

use crate::packet::{DATA_PORT, PAYLOAD_LEN};

/// The sensor's factory address (192.168.1.201) and a broadcast destination.
const SOURCE_IP: [u8; 4] = [192, 168, 1, 201];
const DESTINATION_IP: [u8; 4] = [255, 255, 255, 255];
/// Velodyne's MAC prefix (60:76:88) and a broadcast destination.
const SOURCE_MAC: [u8; 6] = [0x60, 0x76, 0x88, 0x00, 0x00, 0x01];
const DESTINATION_MAC: [u8; 6] = [0xFF; 6];

/// Writes the global header, then one record per packet.
#[derive(Debug)]
pub struct PcapWriter<W: Write> {
    out: W,
    ip_id: u16,
}

fn ipv4_checksum(header: &[u8]) -> u16 {
    let mut sum: u32 = header
        .chunks(2)
        .map(|w| u32::from(u16::from_be_bytes([w[0], w.get(1).copied().unwrap_or(0)])))
        .sum();
    while sum > 0xFFFF {
        sum = (sum & 0xFFFF) + (sum >> 16);
    }
    !(sum as u16)
}

impl<W: Write> PcapWriter<W> {
    /// Writes the global header (magic a1b2c3d4, version 2.4, snap length 65535, Ethernet).
    pub fn new(mut out: W) -> io::Result<Self> {
        out.write_all(&0xA1B2_C3D4u32.to_le_bytes())?;
        out.write_all(&2u16.to_le_bytes())?;
        out.write_all(&4u16.to_le_bytes())?;
        out.write_all(&0i32.to_le_bytes())?;
        out.write_all(&0u32.to_le_bytes())?;
        out.write_all(&65_535u32.to_le_bytes())?;
        out.write_all(&1u32.to_le_bytes())?;
        Ok(Self { out, ip_id: 0 })
    }

    /// Writes one data packet as captured at `time_us` (microseconds since the Unix epoch).
    pub fn write_packet(&mut self, payload: &[u8; PAYLOAD_LEN], time_us: u64) -> io::Result<()> {
        let udp_len = 8 + PAYLOAD_LEN;
        let ip_len = 20 + udp_len;
        let frame_len = 14 + ip_len;
        self.out
            .write_all(&((time_us / 1_000_000) as u32).to_le_bytes())?;
        self.out
            .write_all(&((time_us % 1_000_000) as u32).to_le_bytes())?;
        self.out.write_all(&(frame_len as u32).to_le_bytes())?;
        self.out.write_all(&(frame_len as u32).to_le_bytes())?;
        // Ethernet.
        self.out.write_all(&DESTINATION_MAC)?;
        self.out.write_all(&SOURCE_MAC)?;
        self.out.write_all(&0x0800u16.to_be_bytes())?;
        // IPv4: no options, don't fragment, TTL 64, UDP.
        let mut ip = [0u8; 20];
        ip[0] = 0x45;
        ip[2..4].copy_from_slice(&(ip_len as u16).to_be_bytes());
        ip[4..6].copy_from_slice(&self.ip_id.to_be_bytes());
        ip[6] = 0x40;
        ip[8] = 64;
        ip[9] = 17;
        ip[12..16].copy_from_slice(&SOURCE_IP);
        ip[16..20].copy_from_slice(&DESTINATION_IP);
        let checksum = ipv4_checksum(&ip);
        ip[10..12].copy_from_slice(&checksum.to_be_bytes());
        self.out.write_all(&ip)?;
        self.ip_id = self.ip_id.wrapping_add(1);
        // UDP, checksum 0 (none, allowed over IPv4).
        self.out.write_all(&DATA_PORT.to_be_bytes())?;
        self.out.write_all(&DATA_PORT.to_be_bytes())?;
        self.out.write_all(&(udp_len as u16).to_be_bytes())?;
        self.out.write_all(&0u16.to_be_bytes())?;
        self.out.write_all(payload)
    }

    /// Flushes and returns the writer.
    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn record_layout_and_ip_checksum() {
        let mut w = PcapWriter::new(Vec::new()).unwrap_or_else(|e| panic!("{e}"));
        w.write_packet(&[7u8; PAYLOAD_LEN], 1_500_000_123)
            .unwrap_or_else(|e| panic!("{e}"));
        let bytes = w.finish().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(bytes.len(), 24 + 16 + 14 + 20 + 8 + PAYLOAD_LEN);
        assert_eq!(&bytes[24..28], &1500u32.to_le_bytes());
        assert_eq!(&bytes[28..32], &123u32.to_le_bytes());
        let ip = &bytes[40 + 14..40 + 34];
        // A header with its checksum in place sums to 0xFFFF (complement 0).
        assert_eq!(ipv4_checksum(ip), 0);
        assert_eq!(&bytes[40 + 34..40 + 36], &2368u16.to_be_bytes());
        assert_eq!(bytes[bytes.len() - 1], 7);
    }
}
