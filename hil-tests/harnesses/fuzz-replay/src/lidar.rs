//! Velodyne VLP-16 data packets (`drivers/vlp16`): the decoder, the scan assembler and the
//! health check on a stream of datagrams.

use vlp16::calib::Calibration;
use vlp16::health::{Health, HealthConfig, SensorVerdict};
use vlp16::packet::{DataPacket, PAYLOAD_LEN, PRODUCT_ID_VLP16, PacketError};
use vlp16::scan::ScanAssembler;
use vlp16::{BlindSector, Mount};

use crate::bytes::Bytes;

/// Bytes before the datagrams: configuration (mount, blind sector, capacity, rate) and the
/// arrival step.
pub const HEADER_LEN: usize = 3;

/// A stream of datagrams: a 3-byte header (bit 0: a blind sector behind the sensor; bit 1: a
/// turned, offset mount; bit 2: a 64-point revolution buffer; bit 3: nominal 1200 rpm; the u16
/// after it: the arrival step in 10 us units), then the datagrams, 1206 bytes each (the last may
/// be short). Each is decoded (what decodes re-encodes byte for byte; a wrong length is the only
/// error of a datagram that is not 1206 bytes, and an error's offset lies within the datagram),
/// fed to the health check (its counters add up to the datagrams; an `Ok` verdict has a VLP-16's
/// product id) and to the scan assembler (never more points than its capacity, all finite and
/// within the maximum range of the sensor, each revolution's summary matching its points).
pub fn vlp16_packet(data: &[u8]) {
    let mut b = Bytes::new(data);
    let config = b.u8();
    let step_ns = u64::from(b.u16()) * 10_000;
    let mount = if config & 2 != 0 {
        Mount {
            x_m: 0.3,
            y_m: -0.1,
            z_m: 0.5,
            yaw_rad: 2.0,
        }
    } else {
        Mount::IDENTITY
    };
    let blind: &[BlindSector] = if config & 1 != 0 {
        &[BlindSector {
            from_deg: 150.0,
            to_deg: 210.0,
        }]
    } else {
        &[]
    };
    let capacity = if config & 4 != 0 { 64 } else { 30_000 };
    let calib = Calibration::VLP16;
    let mut scans = match ScanAssembler::new(calib, mount, blind, capacity) {
        Ok(s) => s,
        Err(e) => panic!("the fixed configuration is valid: {e}"),
    };
    let health_config = HealthConfig {
        nominal_rpm: if config & 8 != 0 { 1200.0 } else { 600.0 },
        ..HealthConfig::default()
    };
    let mut health = Health::new(health_config);
    let reach = calib.max_range_m + 0.02 + mount.x_m.hypot(mount.y_m) + mount.z_m;
    let rest = b.rest();
    let mut arrival_ns = 0u64;
    let mut datagrams = 0u64;
    for chunk in rest.chunks(PAYLOAD_LEN) {
        datagrams += 1;
        arrival_ns = arrival_ns.saturating_add(step_ns);
        let decoded = DataPacket::decode(chunk);
        match &decoded {
            Ok(p) => {
                assert_eq!(p.to_bytes()[..], chunk[..], "a decoded packet re-encodes");
            }
            Err(e) => {
                assert_eq!(
                    chunk.len() != PAYLOAD_LEN,
                    matches!(e, PacketError::WrongLength { .. }),
                    "{e}"
                );
                assert!(e.offset() <= chunk.len(), "{e}");
            }
        }
        let Some(packet) = health.on_datagram(chunk, arrival_ns) else {
            continue;
        };
        if let Some(done) = scans.push(&packet, arrival_ns) {
            assert_eq!(done.points, scans.points().len());
            assert!(done.start_us <= done.end_us, "{done:?}");
        }
        let points = scans.points();
        assert!(points.len() <= capacity);
        for p in points {
            let (x, y, z) = (f64::from(p.x), f64::from(p.y), f64::from(p.z));
            assert!(x.is_finite() && y.is_finite() && z.is_finite(), "{p:?}");
            assert!((x * x + y * y + z * z).sqrt() <= reach, "{p:?}");
            assert!(p.laser < 16);
        }
    }
    let stats = health.stats();
    assert_eq!(stats.packets + stats.malformed + stats.short, datagrams);
    assert!(stats.reordered <= stats.packets && stats.foreign <= stats.packets);
    for now in [arrival_ns, arrival_ns.saturating_add(50_000_000), u64::MAX] {
        let verdict = health.verdict(now);
        if verdict == SensorVerdict::Ok {
            assert_eq!(stats.product_id, Some(PRODUCT_ID_VLP16));
        }
        let _ = verdict.to_string();
    }
    if let Some(fault) = stats.last_fault {
        let _ = fault.to_string();
    }
}
